"""Renderer tests: they need a Vulkan driver (make test installs mesa-vulkan-drivers when run as root), and skip,
saying why, only when none can be had. Each module starts one viewer for its pictures; CLI tests start their own
(one per command, as the commands do)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from urdf_pipeline import cli
from urdf_pipeline.errors import UserError
from urdf_pipeline.render.headless_viewer import NO_RENDERER, HeadlessViewer, Size

SMALL = Size(320, 240)


def _no_renderer_reason() -> str | None:
    try:
        with HeadlessViewer(Size(64, 48)):
            return None
    except UserError as exc:
        if exc.message != NO_RENDERER:
            raise
        return f"{exc.message} (make test installs it when run as root)"


@pytest.fixture(scope="session")
def renderer() -> None:
    """Skips a test when this machine cannot draw (no Vulkan driver), with the install line as the reason."""
    reason = _no_renderer_reason()
    if reason is not None:
        pytest.skip(reason)


@pytest.fixture(scope="module")
def viewer(renderer: None) -> Iterator[HeadlessViewer]:
    """One headless viewer for all the pictures of a test module, closed after it."""
    with HeadlessViewer(SMALL) as shared:
        yield shared


@pytest.fixture(scope="session")
def written(examples_dir: Path) -> dict[str, Path]:
    """The demo's and the bimanual example's recordings, written once (up to date afterwards)."""
    outputs = {}
    for name, output in (("demo", "episode_000.rrd"), ("bimanual_pandas", "bimanual_000.rrd")):
        assert cli.main(["run", str(examples_dir / f"{name}.yaml"), "--jobs", "1"]) == 0
        outputs[name] = examples_dir / "out" / output
    return outputs
