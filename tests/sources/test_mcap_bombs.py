"""MCAP decompression bombs: a chunk of a few KB (zstd) or MB (lz4) that inflates to a GiB of zeros, honestly stated
or stating 64 bytes, and a chunk stating a TiB that holds a few KB, built here with the mcap library's record writer
(`write_bomb_bag`), on every topic a config reads (a joint-state source, the robot description, /tf_static, /tf), and
one hidden in the summary section. Each is refused by `validate`, `run` and `init --source` with one `error:` line
naming the file and the chunk's byte offset, nothing written; the bag around each bomb is good (`run` writes it).

And the reader child's own bounds (`URDF_PIPELINE_MCAP_MEMORY_MB`, `URDF_PIPELINE_MCAP_TIMEOUT`): a legitimate 64 MiB
chunk in a child given too little address space, a child given too little time, and SIGTERM to the command, which
leaves no child behind. No timed assertion: each bomb is refused before anything inflates it beyond its bound.
"""

from __future__ import annotations

import io
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("mcap_ros2", reason="writing ROS 2 bags needs mcap-ros2-support (a test dependency)")

from urdf_pipeline.sources import mcap_chunks
from urdf_pipeline.sources.mcap_chunks import McapRefused

from ..bag_inputs import packed, write_bomb_bag, write_robot_bag
from ..conftest import S3
from ..edge_helpers import RIG_URDF, write_config
from .conftest import cached_files

GIB = 1 << 30
MOUNT = ("cam", "camera_optical", (0.01, -0.02, 0.05), (-0.5, 0.5, -0.5, 0.5))
ROWS = 12


@pytest.fixture(scope="module")
def good_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("bags") / "good.mcap"
    moving = [[("odom", "base", (0.1 * row, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))] for row in range(ROWS)]
    write_robot_bag(path, [RIG_URDF], [[MOUNT]], ["shoulder"], np.linspace(0.0, 1.0, ROWS)[:, None], moving)
    return path


def _config(
    directory: Path, bag: str, names: bool = False, urdf: bool = False, tf_static: bool = False, tf: bool = False, url: str = ""
) -> Path:
    """A config reading `data/BAG` (or `url`) for its joint source, and for its robot, /tf_static and /tf edges when asked."""
    source: dict[str, Any] = {"mcap": url or f"data/{bag}", "topic": "/joint_states", **({"names": ["shoulder"]} if names else {})}
    edges = [{"parent": "cam", "child": "camera_optical", "tf_static": f"data/{bag}"}] if tf_static else []
    edges += [{"parent": "odom", "child": "base", "tf": "js"}] if tf else []
    (directory / "rig.urdf").write_text(RIG_URDF, encoding="utf-8")
    data = {
        "version": 1,
        "sources": {"js": source},
        "robots": {
            "rig": {
                "urdf": {"mcap": f"data/{bag}"} if urdf else "rig.urdf",
                "joints": {"source": "js", "unit": "rad", "map": {"shoulder": "shoulder"}},
            }
        },
        "frames": {"root": "odom" if tf else "base"},
        "edges": edges,
        "output": {"path": "out/{segment}.rrd", "application_id": "bombs", "segment": "bag"},
    }
    return write_config(directory, "bag", data)


def _bomb(good: Path, directory: Path, topic: str, compression: str, **options: Any) -> Path:
    path = directory / "data" / "bomb.mcap"
    path.parent.mkdir(parents=True, exist_ok=True)
    write_bomb_bag(good, path, topic, compression, options.pop("inflated", GIB), **options)
    return path


def _one_refusal(result: Any, bag: Path, why: str) -> None:
    lines = result.err.strip().splitlines()
    errors = [line for line in lines if line.startswith("error: ")]
    assert result.code == 1, result.err
    assert len(errors) == 1, result.err
    assert f"MCAP file {bag}, byte " in errors[0] and why in errors[0], errors[0]
    assert "Traceback" not in result.err


TOO_BIG = "bytes uncompressed, beyond the 64 MiB a chunk may hold: a damaged file, or a decompression bomb"
STATES_LESS = "a chunk stating 64 bytes uncompressed inflates to more bytes"
STATES_MORE = "a chunk stating 1,099,511,627,776 bytes uncompressed"


@pytest.mark.parametrize(
    "topic, compression, options, config, why",
    [
        ("/joint_states", "zstd", {}, {}, TOO_BIG),  # the first message's names: read in the child
        ("/joint_states", "lz4", {"stated": 64}, {}, STATES_LESS),
        ("/joint_states", "zstd", {"inflated": 4096, "stated": 1 << 40}, {}, STATES_MORE),
        ("/robot_description", "zstd", {"stated": 64}, {"names": True, "urdf": True}, STATES_LESS),
        ("/tf_static", "lz4", {"stated": 64}, {"names": True, "tf_static": True}, STATES_LESS),
        ("/tf", "zstd", {}, {"names": True, "tf": True}, TOO_BIG),
        ("/joint_states", "zstd", {"in_summary": True}, {"names": True}, "a chunk in the summary section, where none belongs"),
    ],
)
def test_validate_refuses_a_bomb_on_every_topic_it_reads(
    good_bag: Path, tmp_path: Path, run_cli, topic: str, compression: str, options: dict[str, Any], config: dict[str, bool], why: str
) -> None:
    bag = _bomb(good_bag, tmp_path, topic, compression, **options)
    result = run_cli("validate", str(_config(tmp_path, "bomb.mcap", **config)))
    _one_refusal(result, bag, why)


def test_the_bag_around_the_bombs_is_good(good_bag: Path, tmp_path: Path, run_cli) -> None:
    """The same bag with a chunk of 4 KiB of zeros on a topic no one reads: validate and run take it."""
    _bomb(good_bag, tmp_path, "/tf", "zstd", inflated=4096, before=99)
    config = _config(tmp_path, "bomb.mcap", urdf=True, tf_static=True)
    assert run_cli("validate", str(config)).code == 0
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    assert (tmp_path / "out" / "bag.rrd").is_file()


@pytest.mark.parametrize("compression, options", [("zstd", {}), ("lz4", {"stated": 64})])
def test_run_refuses_a_bomb_after_the_first_messages(
    good_bag: Path, tmp_path: Path, run_cli, compression: str, options: dict[str, Any]
) -> None:
    """Names given: validate reads the summary only; run inflates every chunk before Rerun's reader reads any."""
    bag = _bomb(good_bag, tmp_path, "/joint_states", compression, before=ROWS // 2, **options)
    config = _config(tmp_path, "bomb.mcap", names=True)
    assert run_cli("validate", str(config)).code == 0
    result = run_cli("run", str(config))
    _one_refusal(result, bag, TOO_BIG if not options else STATES_LESS)
    assert not (tmp_path / "out").exists()


def test_init_refuses_a_bomb_source(good_bag: Path, tmp_path: Path, run_cli) -> None:
    bag = _bomb(good_bag, tmp_path, "/joint_states", "zstd")
    (tmp_path / "rig.urdf").write_text(RIG_URDF, encoding="utf-8")
    written = tmp_path / "rig.yaml"
    result = run_cli("init", "--urdf", str(tmp_path / "rig.urdf"), "--source", f"mcap:{bag}", "-o", str(written))
    _one_refusal(result, bag, TOO_BIG)
    assert not written.exists()


def test_a_chunk_index_pointing_where_no_chunk_is_met_is_refused(good_bag: Path, tmp_path: Path) -> None:
    """Rerun's reader follows the summary's chunk index, a reader going record by record the framing: a chunk only the
    index points at (hidden in another record's bytes) would be read by one and not checked by the other."""
    data = bytearray(good_bag.read_bytes())
    with good_bag.open("rb") as stream:
        summary = mcap_chunks.read_summary(stream)
    assert summary is not None
    index = summary.chunk_indexes[0]
    at = index.chunk_start_offset
    data[at] = 0x09  # the chunk's record becomes an attachment's, as far as the framing goes: the index still says chunk
    path = tmp_path / "hidden.mcap"
    path.write_bytes(bytes(data))
    with pytest.raises(McapRefused) as refused:
        mcap_chunks.check_chunks(path)
    assert refused.value.at == at and "which the records of the file do not hold" in refused.value.why


@pytest.mark.parametrize("compression", ["zstd", "lz4"])
def test_inflation_stops_one_byte_past_its_bound(compression: str) -> None:
    """A GiB of zeros in a frame that states its size (zstd) or not (lz4), inflated within 1 MiB: 1 MiB + 1 byte come
    back, and the process's peak memory grows by far less than the GiB."""
    import resource

    zeros = bytes(1 << 20)
    data = packed(compression, iter([zeros] * 1024), GIB)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    assert len(mcap_chunks.inflate(compression, data, 1 << 20)) == (1 << 20) + 1
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - peak < 64 << 10  # KiB


def test_the_reader_child_is_bounded_in_memory(good_bag: Path, tmp_path: Path, run_cli, monkeypatch: pytest.MonkeyPatch) -> None:
    """A 64 MiB chunk (the most one may hold) is read by the child within its default 1024 MB of address space, and
    refused, naming the bound, in a child given 650 MB."""
    _bomb(good_bag, tmp_path, "/robot_description", "zstd", inflated=64 << 20)
    config = _config(tmp_path, "bomb.mcap")
    assert run_cli("validate", str(config)).code == 0
    monkeypatch.setenv("URDF_PIPELINE_MCAP_MEMORY_MB", "650")
    result = run_cli("validate", str(config))
    assert result.code == 1 and result.err.count("error: ") == 1, result.err
    assert "of MCAP file" in result.err and "needs more than 650 MB of memory" in result.err, result.err
    assert "URDF_PIPELINE_MCAP_MEMORY_MB" in result.err


def test_the_reader_child_is_bounded_in_time(good_bag: Path, tmp_path: Path, run_cli, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("URDF_PIPELINE_MCAP_TIMEOUT", "0.05")
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "good.mcap").write_bytes(good_bag.read_bytes())
    result = run_cli("validate", str(_config(tmp_path, "good.mcap")))
    assert result.code == 1 and result.err.count("error: ") == 1, result.err
    assert "did not finish within 0.05 s and was stopped" in result.err and "URDF_PIPELINE_MCAP_TIMEOUT" in result.err
    monkeypatch.setenv("URDF_PIPELINE_MCAP_TIMEOUT", "soon")
    result = run_cli("validate", str(_config(tmp_path, "good.mcap")))
    assert result.code == 1 and "URDF_PIPELINE_MCAP_TIMEOUT='soon' must be a positive number" in result.err


def _children(marker: str) -> list[int]:
    """The processes whose command line names `marker` (the reader children of one test's bag)."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                if marker in (entry / "cmdline").read_bytes().decode("utf-8", "replace"):
                    found.append(int(entry.name))
            except OSError:
                continue
    return found


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("sent", [signal.SIGTERM, signal.SIGKILL])
def test_the_reader_child_ends_with_the_command(good_bag: Path, tmp_path: Path, sent: signal.Signals) -> None:
    """SIGTERM (or SIGKILL) to `validate` while its reader child runs: no child is left behind."""
    (tmp_path / "data").mkdir()
    bag = tmp_path / "data" / "good.mcap"
    bag.write_bytes(good_bag.read_bytes())
    config = _config(tmp_path, "good.mcap", urdf=True, tf_static=True)
    command = subprocess.Popen(
        [sys.executable, "-m", "urdf_pipeline", "validate", str(config)], stderr=subprocess.PIPE, stdout=subprocess.DEVNULL
    )
    deadline = time.monotonic() + 60
    while not _children(f"\x00{bag}\x00") and command.poll() is None:
        assert time.monotonic() < deadline, "no reader child started"
        time.sleep(0.02)
    command.send_signal(sent)
    _, err = command.communicate(timeout=30)
    assert command.returncode == (143 if sent == signal.SIGTERM else -signal.SIGKILL), err
    deadline = time.monotonic() + 10
    while _children(f"\x00{bag}\x00"):
        assert time.monotonic() < deadline, "a reader child outlived the command"
        time.sleep(0.05)
    assert b"Traceback" not in err


@pytest.mark.parametrize(
    "options, why",
    [
        ({"stated": 64}, STATES_LESS),  # the first message's chunk, read for its names
        ({}, TOO_BIG),
        ({"in_summary": True}, "a chunk in the summary section, where none belongs"),  # the summary, read by ranged GETs
    ],
)
def test_a_bomb_on_s3_is_refused_from_its_ranged_reads(
    good_bag: Path, tmp_path: Path, s3: S3, cache: Path, run_cli, options: dict[str, Any], why: str
) -> None:
    bag = _bomb(good_bag, tmp_path, "/joint_states", "lz4" if options.get("stated") else "zstd", **options)
    s3.client().upload_file(str(bag), s3.bucket, "bombs/bomb.mcap")
    url = s3.url("bombs/bomb.mcap")
    result = run_cli("validate", str(_config(tmp_path, "bomb.mcap", url=url)))
    errors = [line for line in result.err.splitlines() if line.startswith("error: ")]
    assert result.code == 1 and len(errors) == 1, result.err
    assert f"MCAP file {url}, byte " in errors[0] and why in errors[0], errors[0]
    assert cached_files(cache) == []


def test_late_log_times_are_counted_from_bounded_chunks(good_bag: Path, tmp_path: Path) -> None:
    """The late-message count behind a log time beyond 2262 (local and remote files) reads chunks through the same bound."""
    from urdf_pipeline.sources.mcap_remote import late_messages

    bag = _bomb(good_bag, tmp_path, "/joint_states", "zstd", stated=64)
    with pytest.raises(McapRefused, match="inflates to more bytes"), io.BytesIO(bag.read_bytes()) as stream:
        late_messages(stream, "/joint_states", 0)
    with good_bag.open("rb") as stream:
        assert late_messages(stream, "/joint_states", 0) == ROWS


def test_a_robot_description_longer_than_a_pipe_holds_is_read(tmp_path: Path, run_cli) -> None:
    """The child's answer (a 300 KB description) is read while the child writes it: a pipe holds 64 KiB."""
    urdf = RIG_URDF.replace("</robot>", "<!--" + "x" * 300_000 + "--></robot>")
    write_robot_bag(tmp_path / "data" / "long.mcap", [urdf], [], ["shoulder"], np.zeros((3, 1)))
    result = run_cli("validate", str(_config(tmp_path, "long.mcap", urdf=True)))
    assert result.code == 0, result.err


@pytest.mark.parametrize("compression", ["zstd", "lz4", ""])
def test_a_chunk_stating_more_than_it_holds_is_refused_without_allocating_it(good_bag: Path, tmp_path: Path, compression: str) -> None:
    """Stating 32 MiB (within the bound) and holding 4 KiB: refused from the bytes it produced, at the chunk's offset."""
    bag = _bomb(good_bag, tmp_path, "/joint_states", compression, inflated=4096, stated=32 << 20)
    with pytest.raises(McapRefused) as refused:
        mcap_chunks.check_chunks(bag)
    assert "a chunk stating 33,554,432 bytes uncompressed inflates to 4,096 bytes" in refused.value.why
    with bag.open("rb") as stream:
        summary = mcap_chunks.read_summary(stream)
    assert summary is not None and refused.value.at in {index.chunk_start_offset for index in summary.chunk_indexes}


def test_many_chunks_of_zeros_each_within_the_bound_are_refused_in_proportion_to_the_file(good_bag: Path, tmp_path: Path, run_cli) -> None:
    """200 chunks of 2 KB, each honestly 64 MiB of zeros (12.5 GiB from a 450 KB file): refused once the file has
    inflated 256 MiB plus 1000 times the compressed bytes read, at the fifth."""
    bag = _bomb(good_bag, tmp_path, "/joint_states", "zstd", inflated=64 << 20, count=200, before=ROWS)
    config = _config(tmp_path, "bomb.mcap", names=True)
    assert run_cli("validate", str(config)).code == 0  # the summary only
    result = run_cli("run", str(config))
    _one_refusal(result, bag, "more than 1000 times their size beyond the first 256 MiB: a decompression bomb")
    assert not (tmp_path / "out").exists()
