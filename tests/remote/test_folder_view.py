"""A local folder of remote files (what Rerun's LeRobotReader reads a remote episode from): each file a link at its
path to its cached copy, the folder removed however the block ends, and no path from a stranger's listing or template
able to place a link outside it. The files here are Hub files read offline from a cache in the client's layout."""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest

from urdf_pipeline.errors import UserError
from urdf_pipeline.plan import RemoteObject
from urdf_pipeline.remote import check_relative, fetched_folder

from ..lerobot_layouts import hub_commit

COMMIT = hashlib.sha1(b"view").hexdigest()


@pytest.mark.parametrize(
    "path",
    ["", "/etc/passwd", "meta/../../x", "meta//x", "./meta", "meta/..", "meta\\..\\x", "meta/x\n", "a" * 256, "meta/\u202ex"],
)
def test_a_path_that_could_leave_the_folder_is_refused(path: str) -> None:
    with pytest.raises(UserError, match="does not name a place inside the dataset's folder"):
        check_relative(path, None)


def test_the_files_are_linked_at_their_paths_and_the_folder_is_removed(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("huggingface_hub", reason="the hub extra: pip install 'urdf-pipeline[hub]'")
    dataset = tmp_path / "dataset"
    (dataset / "meta").mkdir(parents=True)
    (dataset / "meta" / "info.json").write_text('{"codebase_version": "v2.1"}')
    (dataset / "data").mkdir()
    (dataset / "data" / "episode_000000.parquet").write_bytes(b"PAR1 not really")
    hub_commit(tmp_path / "hub", "robots/view", dataset, COMMIT)
    monkeypatch.setenv("HF_HUB_CACHE", str(tmp_path / "hub"))
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    base = f"hf://datasets/robots/view@{COMMIT}"
    files = {name: RemoteObject(f"{base}/{name}", COMMIT, 0) for name in ("meta/info.json", "data/episode_000000.parquet")}

    with fetched_folder(files, None) as folder:
        assert (folder / "meta" / "info.json").read_text() == '{"codebase_version": "v2.1"}'
        assert (folder / "data" / "episode_000000.parquet").read_bytes() == b"PAR1 not really"
        assert sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file()) == sorted(files)
    assert not folder.exists()

    with pytest.raises(RuntimeError), fetched_folder(files, None) as folder:
        raise RuntimeError("the segment failed")
    assert not folder.exists(), "removed however the block ends"

    with pytest.raises(UserError, match="does not name a place inside"), fetched_folder({"../x": files["meta/info.json"]}, None):
        pass
