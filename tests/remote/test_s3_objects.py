"""S3 objects against a real S3 endpoint (moto_server on 127.0.0.1): identity by ETag, listing, ranged reads that
fetch a parquet footer without the data, downloads pinned to the planned ETag, uploads, and errors that name the URL."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from urdf_pipeline.errors import UserError
from urdf_pipeline.remote import parse_url
from urdf_pipeline.remote.s3_objects import RangeFile, download, head, listing, open_range, upload

from ..conftest import S3


def _parquet(path: Path, rows: int) -> None:
    values = np.random.default_rng(0).random((rows, 6))
    table = pa.table({"frame": np.arange(rows), "observation.state": pa.array(list(values), type=pa.list_(pa.float64()))})
    pq.write_table(table, path)


def test_head_list_range_download_upload(s3: S3, tmp_path: Path) -> None:
    local = tmp_path / "episode.parquet"
    _parquet(local, 200_000)
    uploaded = upload(local, parse_url(s3.url("so101/episode_0.parquet")), None)
    assert uploaded.size == local.stat().st_size and uploaded.version
    assert head(parse_url(s3.url("so101/episode_0.parquet")), None) == uploaded
    s3.client().put_object(Bucket=s3.bucket, Key="so101/meta/info.json", Body=b"{}")
    assert [o.url for o in listing(parse_url(s3.url("so101/")), None)] == [
        s3.url("so101/episode_0.parquet"),
        s3.url("so101/meta/info.json"),
    ]

    raw = RangeFile(uploaded, None)
    import io

    schema = pq.read_schema(io.BufferedReader(raw, 1 << 16))  # the footer: a few ranged GETs, not the file
    assert schema.names == ["frame", "observation.state"]
    assert raw.requests <= 3 and uploaded.size > 5_000_000
    with open_range(uploaded, None) as reader:
        assert pq.ParquetFile(reader).metadata.num_rows == 200_000

    target = tmp_path / "copy.parquet"
    download(uploaded, target, None)
    assert target.read_bytes() == local.read_bytes()


def test_an_object_changed_after_planning_is_refused(s3: S3, tmp_path: Path) -> None:
    url = parse_url(s3.url("episode.parquet"))
    s3.client().put_object(Bucket=s3.bucket, Key=url.key, Body=b"first version")
    planned = head(url, None)
    s3.client().put_object(Bucket=s3.bucket, Key=url.key, Body=b"second version, another ETag")
    with pytest.raises(UserError) as caught:
        download(planned, tmp_path / "x", None)
    assert "changed after it was planned" in caught.value.message and url.url in caught.value.message
    with pytest.raises(UserError, match="changed after it was planned"):
        RangeFile(planned, None).read(4)


def test_a_missing_key_or_bucket_names_the_url(s3: S3) -> None:
    with pytest.raises(UserError, match=r"cannot read s3://.*/nothing-here\.parquet: no such object \(404\)"):
        head(parse_url(s3.url("nothing-here.parquet")), None)
    with pytest.raises(UserError, match="no such bucket"):
        listing(parse_url("s3://no-such-bucket-here/x/"), None)
