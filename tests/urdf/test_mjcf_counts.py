"""MJCF size bombs (a few bytes asking MuJoCo for gigabytes or hours) are refused by the scan before MuJoCo compiles,
in one line naming the file, its line and the element or attribute; what real robots hold passes (the MJCF sweep,
test_mjcf_sweep.py, is every model dm_control ships)."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import pytest

from urdf_pipeline.urdf.mjcf_counts import MAX_ELEMENTS, MAX_NESTING, MAX_NUMBERS

from ..mjcf_inputs import REPLICATE_BOMB, robot_config
from .test_mjcf_files import refused

pytest.importorskip("mujoco", reason="MJCF robots need mujoco (pip install 'urdf-pipeline[mjcf]')")


def _refused(tmp_path: Path, run_cli, files: dict[str, str], *expected: str) -> None:
    for name, text in files.items():
        (tmp_path / name).write_text(text, encoding="utf-8")
    config = robot_config(tmp_path, {"mjcf": "robot.xml"}, "j")
    refused(run_cli("validate", str(config)), config, *expected, "MuJoCo would need far more memory and time")


def _worldbody(inside: str) -> str:
    return f"<mujoco>\n<worldbody>\n{inside}\n</worldbody>\n</mujoco>\n"


def test_nested_replicates_multiply(tmp_path: Path, run_cli) -> None:
    assert len(REPLICATE_BOMB) < 1000  # 10^8 bodies
    _refused(
        tmp_path,
        run_cli,
        {"robot.xml": REPLICATE_BOMB},
        f"robot.xml:1: <replicate> brings the model to more than {MAX_ELEMENTS:,} elements after includes, replicates and "
        "attachments (the replicates around it make 10,000 copies of it)",
    )


def test_one_huge_replicate_is_refused_at_its_count(tmp_path: Path, run_cli) -> None:
    _refused(
        tmp_path,
        run_cli,
        {"robot.xml": _worldbody('<replicate count="1000000000" offset="0 0 0"/>')},
        "robot.xml:3: <replicate count='1000000000'> makes 1,000,000,000 copies of what it holds",
    )


def test_a_count_that_is_no_number_is_refused(tmp_path: Path, run_cli) -> None:
    _refused(tmp_path, run_cli, {"robot.xml": _worldbody('<replicate count="1e999"/>')}, "<replicate count='1e999'> is not a count")


def test_deep_nesting_is_refused(tmp_path: Path, run_cli) -> None:
    chain = "<body>" * 5000 + '<geom size="0.1"/>' + "</body>" * 5000
    _refused(tmp_path, run_cli, {"robot.xml": _worldbody(chain)}, f"robot.xml:3: <body> is nested more than {MAX_NESTING} elements deep")


def test_elements_are_counted_across_includes(tmp_path: Path, run_cli) -> None:
    part = "<mujoco>\n" + '<site size="0.01"/>\n' * 4000 + "</mujoco>\n"
    includes = "\n".join(f'<include file="part{index}.xml"/>' for index in range(3))
    files = {"robot.xml": _worldbody(includes), **{f"part{index}.xml": part for index in range(3)}}
    # 5 elements of robot.xml and 2 x (4000 + 1) of the first two parts: part2's 1,993rd site (its line 1,994) crosses.
    _refused(tmp_path, run_cli, files, f"part2.xml:1994: <site> brings the model to more than {MAX_ELEMENTS:,} elements")


def test_an_attached_model_counts_at_each_attach(tmp_path: Path, run_cli) -> None:
    hand = "<mujoco>\n<worldbody>\n<body name='hand'>\n" + '<site size="0.01"/>\n' * 4000 + "</body>\n</worldbody>\n</mujoco>\n"
    attaches = "\n".join(f'<body name="b{index}"><attach model="hand" body="hand" prefix="h{index}"/></body>' for index in range(3))
    robot = f'<mujoco>\n<asset><model name="hand" file="hand.xml"/></asset>\n<worldbody>\n{attaches}\n</worldbody>\n</mujoco>\n'
    _refused(
        tmp_path,
        run_cli,
        {"robot.xml": robot, "hand.xml": hand},
        "robot.xml:6: <attach> brings the model, with the attached one, beyond its bounds (10,000 elements",
    )


@pytest.mark.parametrize(
    ("element", "expected"),
    [
        ('<composite type="cable" count="100000 1 1"/>', "<composite count='100000 1 1'> brings the model to more than 10,000 elements"),
        ('<flexcomp type="grid" count="1000 1000 1" spacing="1 1 1"/>', "<flexcomp count='1000 1000 1'> brings the model to more than"),
    ],
)
def test_generated_points_are_counted(tmp_path: Path, run_cli, element: str, expected: str) -> None:
    _refused(tmp_path, run_cli, {"robot.xml": _worldbody(f'<body name="b">{element}</body>')}, f"robot.xml:3: {expected}")


@pytest.mark.parametrize(
    ("asset", "expected"),
    [
        (
            '<texture name="t" type="2d" builtin="checker" width="30000" height="30000"/>',
            "<texture width='30000'> brings the model's texture pixels to more than 16,777,216 (4096 x 4096)",
        ),
        (
            '<texture name="t" type="skybox" builtin="gradient" width="2000" height="2000"/>',
            "<texture width='2000'> brings the model's texture pixels to more than",
        ),
        ('<hfield name="h" nrow="100000" ncol="100000" size="1 1 1 1"/>', "<hfield nrow='100000'> brings the model's height field samples"),
        ('<numeric name="n" size="50000000"/>', "<numeric size='50000000'> brings the numbers"),
        (
            '<mesh name="m" vertex="{}"/>'.format("0 " * (MAX_NUMBERS + 1)),
            f"(2,000,002 characters)> brings the numbers written in the model's attributes to more than {MAX_NUMBERS:,}",
        ),
    ],
)
def test_asset_sizes_are_bounded(tmp_path: Path, run_cli, asset: str, expected: str) -> None:
    parent = "custom" if asset.startswith("<numeric") else "asset"
    _refused(tmp_path, run_cli, {"robot.xml": f"<mujoco>\n<{parent}>\n{asset}\n</{parent}>\n</mujoco>\n"}, "robot.xml:3: <", expected)


def test_declared_rows_are_bounded(tmp_path: Path, run_cli) -> None:
    robot = '<mujoco>\n<size nuser_geom="20000000"/>\n<worldbody><geom size="1"/></worldbody>\n</mujoco>\n'
    _refused(tmp_path, run_cli, {"robot.xml": robot}, "robot.xml:2: <size nuser_geom='20000000'> asks for more than 1,000 rows")


def _png(width: int, height: int) -> bytes:
    """A grey PNG of `width` x `height` whose rows are all zero: a few hundred KB that decode to width x height bytes."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    packer = zlib.compressobj(9)
    rows = b"".join(packer.compress(b"\0" * (width + 1)) for _ in range(height)) + packer.flush()
    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", rows) + chunk(b"IEND", b"")


@pytest.mark.parametrize(
    ("element", "expected"),
    [
        (
            '<texture name="t" type="2d" file="big.png"/>',
            "<texture file='big.png'> is a PNG of 20,000 x 20,000, which brings the model's texture pixels",
        ),
        (
            '<hfield name="h" file="big.png" size="1 1 1 1"/>',
            "<hfield file='big.png'> is a PNG of 20,000 x 20,000, which brings the model's height field",
        ),
    ],
)
def test_a_png_is_counted_by_the_size_it_states(tmp_path: Path, run_cli, element: str, expected: str) -> None:
    """MuJoCo decoded this 400 KB PNG into 2.4 GB in 4 s, within its child's bounds: the scan reads its header."""
    (tmp_path / "big.png").write_bytes(_png(20_000, 20_000))
    _refused(tmp_path, run_cli, {"robot.xml": f"<mujoco>\n<asset>\n{element}\n</asset>\n</mujoco>\n"}, f"robot.xml:3: {expected}")
