"""`dataset.base_files` (what `run --base` and `browse --base` read): the base recordings by recording id, each file
kept inside the folder `--base` names, symlinks followed, a regular file holding a Rerun recording. Every hostile
folder is built here."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from urdf_pipeline.dataset import base_files
from urdf_pipeline.errors import UserError


def recording(path: Path, recording_id: str) -> None:
    import rerun as rr

    stream = rr.RecordingStream(application_id="base", recording_id=recording_id)
    path.parent.mkdir(parents=True, exist_ok=True)
    stream.save(str(path))
    stream.log("x", rr.Scalars(1.0))
    stream.disconnect()


def test_files_inside_the_folder_are_found_by_recording_id(tmp_path: Path) -> None:
    base = tmp_path / "base"
    recording(base / "a.rrd", "episode_0")
    recording(base / "nested" / "b.rrd", "episode_1")
    (base / "inside_link.rrd").symlink_to(base / "a.rrd")  # a link that stays inside is followed
    (base / "folder.rrd").mkdir()  # a folder named like a recording: nothing to read
    found = base_files(str(base))
    assert sorted(found) == ["episode_0", "episode_1"]
    assert {f.path for f in found["episode_0"]} == {(base / "a.rrd").resolve()}  # resolved: the file itself
    assert base_files(str(base / "*.rrd")).keys() == {"episode_0"}
    assert base_files(str(base / "**" / "*.rrd")).keys() == {"episode_0", "episode_1"}


@pytest.mark.parametrize("given", ["folder", "glob", "nested glob"])
def test_a_link_out_of_the_folder_is_refused(tmp_path: Path, given: str) -> None:
    base = tmp_path / "base"
    recording(base / "a.rrd", "episode_0")
    recording(tmp_path / "elsewhere" / "b.rrd", "episode_1")  # a recording, but outside the folder --base names
    (base / "sub").mkdir()
    (base / "sub" / "b.rrd").symlink_to(tmp_path / "elsewhere" / "b.rrd")
    (base / "sub" / "c.rrd").symlink_to("/etc/passwd")
    pattern = {"folder": str(base), "glob": str(base / "sub" / "*.rrd"), "nested glob": str(base / "**" / "*.rrd")}[given]
    with pytest.raises(UserError) as refused:
        base_files(pattern)
    assert "outside" in refused.value.message and "symbolic link" in refused.value.message
    assert refused.value.where is not None and str(refused.value.where.file) == "--base"


def test_a_fifo_or_a_file_that_is_no_recording_is_refused(tmp_path: Path) -> None:
    base = tmp_path / "base"
    base.mkdir()
    os.mkfifo(base / "a.rrd")  # reading it would wait forever
    with pytest.raises(UserError, match="FIFO"):
        base_files(str(base))
    (base / "a.rrd").unlink()
    (base / "a.rrd").write_text("<script>alert(1)</script>")
    with pytest.raises(UserError, match="cannot read base recording"):
        base_files(str(base))
