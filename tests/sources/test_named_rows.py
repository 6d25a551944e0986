"""Rows naming their own values -> a matrix in the source's name order, columnar."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest

from urdf_pipeline.errors import UserError, Where
from urdf_pipeline.plan import McapSourcePlan
from urdf_pipeline.sources.named_rows import NAME_FIELD, VALUE_FIELD, is_named_rows, named_matrix, named_rows_column

SOURCE = McapSourcePlan("js", Path("run.mcap"), "/joint_states", "ros2_timestamp", ("a", "b", "c"), Where(Path("c.yaml"), 3))


def rows(names: list[list[str]], values: list[list[float]]) -> pa.StructArray:
    column = named_rows_column(pa.array(names, pa.list_(pa.string())), pa.array(values, pa.list_(pa.float64())))
    return column.flatten()


def test_values_land_in_the_source_order_whatever_the_row_order() -> None:
    batch = rows([["a", "b", "c"], ["c", "a", "b"], ["b", "c", "a"]], [[1, 2, 3], [30, 10, 20], [200, 300, 100]])
    assert is_named_rows(batch)
    np.testing.assert_array_equal(named_matrix(batch, SOURCE, [0, 1, 2], "robot 'arm'"), [[1, 2, 3], [10, 20, 30], [100, 200, 300]])


def test_sliced_rows_keep_their_offsets() -> None:
    batch = rows([["a", "b", "c"], ["c", "b", "a"], ["b", "a", "c"], ["a", "c", "b"]], [[1, 2, 3], [6, 5, 4], [8, 7, 9], [10, 12, 11]])
    np.testing.assert_array_equal(named_matrix(batch.slice(1, 2), SOURCE, [0, 1, 2], "robot 'arm'"), [[4, 5, 6], [7, 8, 9]])
    assert pa.types.is_struct(batch.type) and {f.name for f in batch.type} == {NAME_FIELD, VALUE_FIELD}


def test_a_name_nobody_reads_may_be_absent() -> None:
    matrix = named_matrix(rows([["a", "b"], ["b", "c", "a"]], [[1, 2], [5, 6, 4]]), SOURCE, [0, 1], "robot 'arm'")
    np.testing.assert_array_equal(matrix[:, :2], [[1, 2], [4, 5]])
    assert np.isnan(matrix[0, 2]) and matrix[1, 2] == 6


@pytest.mark.parametrize(
    ("names", "values", "expected"),
    [
        ([["a", "b"], ["a", "b", "c"]], [[1, 2], [1, 2, 3]], "source 'js' rows lack names that robot 'arm' maps: 'c' from 1 of 2 rows"),
        ([["a", "b", "c", "d"]], [[1, 2, 3, 4]], "source 'js' has rows naming 'd', not among its names (1 of 1 rows"),
        ([["a", "b", "c"], ["a", "b", "c"]], [[1, 2, 3], [1, 2, 3, 4]], "source 'js' has rows of 4 values but 3 names (1 of 2 rows"),
        ([["a", "a", "b", "c"]], [[1, 2, 3, 4]], "source 'js' names 'a' 2 times in one row"),
    ],
    ids=["lacking", "unknown", "count", "twice"],
)
def test_refused_rows(names: list[list[str]], values: list[list[float]], expected: str) -> None:
    with pytest.raises(UserError) as error:
        named_matrix(rows(names, values), SOURCE, [0, 1, 2], "robot 'arm'")
    assert expected in error.value.message
    assert error.value.where == SOURCE.where
