"""One headless Rerun viewer per command, driven through `rerun.experimental.ViewerClient`, reused for every picture.

Why it is started here and not with `ViewerClient.spawn`: spawn cannot pass `--window-size` (the picture's size),
`--bind 127.0.0.1` (spawn listens on every interface) or `--renderer vulkan` (the GL fallback panics on a software
rasterizer), and it sends the viewer's log lines to our stderr. So rerun-sdk's viewer binary runs as a child in a
session of its own, its output in a log file; `close` (also at exit) ends it, whatever way the command ends.

Why the recordings are sent through a RecordingStream and not opened with `ViewerClient.open`: opened files arrive
as a catalog dataset whose application id is a hash, and a blueprint sent for the config's application id does not
apply to them. Sent through a stream, they keep their application id, and each picture's blueprint is sent on it.
"""

from __future__ import annotations

import atexit
import io
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import UserError
from ..process import held_off, log_reason, start_viewer, stop_session, viewer_binary, viewer_url
from .camera import Camera
from .frames import Timeline

if TYPE_CHECKING:
    import rerun as rr
    from rerun.chunk import Chunk
    from rerun.experimental import ViewerClient

NO_RENDERER = (
    "cannot draw pictures: the Rerun viewer found no Vulkan driver; install one "
    "(apt-get install mesa-vulkan-drivers, a software renderer for any machine, or your GPU's Vulkan driver)"
)
CHROME = (7 + 8, 43)  # points the window keeps around its views with every panel hidden (rerun-sdk 0.41), +8 cropped
NOTIFICATIONS_WIDTH = 360  # the notifications ("toasts") are at most 330 points wide, 8 from the right edge
STARTUP_SECONDS = 30.0
ARRIVAL_SECONDS = 60.0
SETTLE_ATTEMPTS = 6


@dataclass(frozen=True)
class Size:
    width: int
    height: int

    @staticmethod
    def parse(text: str) -> Size:
        """`WxH`, each between 16 and 8192 pixels."""
        width, _, height = text.lower().partition("x")
        if not (width.isdigit() and height.isdigit()) or not (16 <= int(width) <= 8192 and 16 <= int(height) <= 8192):
            raise ValueError(f"'{text}' is not WIDTHxHEIGHT with each between 16 and 8192 (e.g. 1024x768)")
        return Size(int(width), int(height))


@dataclass(frozen=True)
class Shot:
    """One picture: the camera, what the view holds (entity path queries), and when."""

    camera: Camera
    contents: tuple[str, ...] = ("/**",)
    timeline: Timeline | None = None
    time: int | None = None  # on `timeline`: a sequence number, or nanoseconds


@dataclass(frozen=True)
class _Shown:
    location: str
    stream: rr.RecordingStream


class HeadlessViewer:
    """`with HeadlessViewer(size) as viewer: viewer.show(...); viewer.draw(...)`: one viewer process for all of it."""

    def __init__(self, size: Size) -> None:
        self.size = size
        self._folder = Path(tempfile.mkdtemp(prefix="urdf-pipeline-viewer-"))
        self._log_path = self._folder / "viewer.log"
        self._process: subprocess.Popen[bytes] | None = None
        self._shown: dict[str, _Shown] = {}
        atexit.register(self.close)
        try:
            port = _free_port()
            self._process = _start(self._folder, self._log_path, size, port)
            self.client = self._connect(port)
        except BaseException:
            self.close()
            raise

    def __enter__(self) -> HeadlessViewer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def url(self) -> str:
        return self.client.url

    def _connect(self, port: int) -> ViewerClient:
        from rerun.experimental import ViewerClient

        deadline = time.monotonic() + STARTUP_SECONDS
        while True:
            try:
                client = ViewerClient.connect(viewer_url(port))  # connects at once: retried
                client.get_state()
                return client
            except (ConnectionError, RuntimeError, TimeoutError, OSError):
                self._raise_if_stopped()
                if time.monotonic() > deadline:
                    raise UserError(f"the Rerun viewer did not answer within {STARTUP_SECONDS:.0f} s{self._log_tail()}") from None
                time.sleep(0.05)

    def _raise_if_stopped(self) -> None:
        if self._process is not None and self._process.poll() is not None:
            log = self._log_path.read_text(encoding="utf-8", errors="replace") if self._log_path.exists() else ""
            if "No graphics adapter" in log or "Failed to create render state" in log:
                raise UserError(NO_RENDERER)
            raise UserError(f"the Rerun viewer stopped (exit status {self._process.returncode}){self._log_tail()}")

    def _log_tail(self) -> str:
        with open(self._log_path, "rb") as log:  # written since the viewer's start
            return log_reason(log)

    def _call(self, call: Callable[[], Any]) -> Any:
        """A viewer request; if the viewer died meanwhile, say so as a user error rather than a connection traceback."""
        try:
            return call()
        except (ConnectionError, RuntimeError, TimeoutError, OSError):
            self._raise_if_stopped()
            raise

    def show(self, application_id: str, recording_id: str, chunks: Sequence[Chunk]) -> str:
        """Send one recording's chunks; returns its store id once the viewer holds every entity sent."""
        import rerun as rr

        stream = rr.RecordingStream(application_id, recording_id=recording_id, send_properties=False)
        try:
            stream.connect_grpc(self.url)
            stream.send_chunks(list(chunks))
            stream.flush()
            return self._arrived(application_id, recording_id, chunks, stream)
        except BaseException:
            stream.disconnect()
            raise

    def _arrived(self, application_id: str, recording_id: str, chunks: Sequence[Chunk], stream: rr.RecordingStream) -> str:
        store_id = f"Recording:{_escaped(application_id)}:{recording_id}"
        entities = {chunk.entity_path for chunk in chunks}
        deadline = time.monotonic() + ARRIVAL_SECONDS
        while True:
            state = self._call(self.client.get_state)
            recording = next((r for r in state.recordings if r.store_id == store_id), None)
            if recording is not None and not state.loading:
                schema = self._call(lambda: self.client.get_recording_schema(store_id, paths_only=True, max_entities=100_000))
                held = {entity.entity_path for entity in schema.entities}
                if entities <= held or len(held) >= len(entities):  # the count too, should a path be spelled otherwise
                    self._shown[store_id] = _Shown(recording.location, stream)
                    return store_id
            if time.monotonic() > deadline:
                raise RuntimeError(f"the viewer did not receive {store_id} within {ARRIVAL_SECONDS:.0f} s")
            time.sleep(0.05)

    def draw(self, store_id: str, shot: Shot) -> bytes:
        """`shot` of a shown recording, as PNG bytes at the viewer's size."""
        import rerun.blueprint as rrb

        shown = self._shown[store_id]
        camera = shot.camera
        eye = rrb.EyeControls3D(position=camera.position, look_target=camera.target, eye_up=camera.up)
        view = rrb.Spatial3DView(origin="/", contents=list(shot.contents), name="picture", titlebar=False, eye_controls=eye)
        # The viewer's notifications float at the window's top right: an empty column there keeps them off the view.
        spacer = rrb.TextDocumentView(origin="/__urdf_pipeline_spacer", name="spacer", titlebar=False)
        timeline = shot.timeline.name if shot.timeline is not None else None
        blueprint = rrb.Blueprint(
            rrb.Horizontal(view, spacer, column_shares=[self.size.width, NOTIFICATIONS_WIDTH]),
            rrb.TopPanel(state="hidden"),
            rrb.BlueprintPanel(state="hidden"),
            rrb.SelectionPanel(state="hidden"),
            rrb.TimePanel(state="hidden", timeline=timeline, play_state="paused"),
            auto_views=False,
        )
        self._call(lambda: self.client.set_location(shown.location))
        shown.stream.send_blueprint(blueprint, make_active=True, make_default=True)
        shown.stream.flush()
        self._await_view(store_id, str(view.id), camera)
        if shot.timeline is not None and shot.time is not None:
            self._set_time(store_id, shot.timeline, shot.time)
        return _cropped(self._settled(str(view.id)), self.size)

    def _settled(self, view_id: str) -> bytes:
        """The view once two screenshots in a row are the same (a scene still loading would move)."""
        previous = b""
        for _ in range(SETTLE_ATTEMPTS):
            png = bytes(self._call(lambda: self.client.take_screenshot(view_id)))
            if png == previous:
                return png
            previous = png
        return previous

    def _await_view(self, store_id: str, view_id: str, camera: Camera) -> None:
        """Until the viewer shows the view just sent; then its eye, read back, must be the camera asked for."""
        deadline = time.monotonic() + ARRIVAL_SECONDS
        while not any(v.view_id == view_id for v in self._call(self.client.get_state).views):
            if time.monotonic() > deadline:
                raise RuntimeError(f"the viewer did not show the picture's view {view_id} within {ARRIVAL_SECONDS:.0f} s")
            time.sleep(0.02)
        blueprint = self._call(lambda: self.client.get_blueprint(of="recording", store_id=store_id)).blueprint
        eye = blueprint.get(f"/view/{view_id}/EyeControls3D", {}).get("EyeControls3D", {})
        expected = {"position": camera.position, "look_target": camera.target, "eye_up": camera.up}
        if any(not np.allclose(eye.get(key, np.nan), value, atol=1e-4) for key, value in expected.items()):
            raise RuntimeError(f"the viewer's eye {eye} is not the camera sent {expected}")

    def _set_time(self, store_id: str, timeline: Timeline, value: int) -> None:
        at = {"sequence": int(value), "duration": np.timedelta64(int(value), "ns"), "timestamp": np.datetime64(int(value), "ns")}
        self._call(
            lambda: self.client.set_time(timeline.name, **{timeline.kind: at[timeline.kind]}, play_state="paused", recording=store_id)
        )

    def transform_graph(self, store_id: str, timeline: Timeline | None = None, value: int | None = None) -> dict[str, Any]:
        """The viewer's own transform graph of a shown recording (at `value` on `timeline` when given)."""
        shown = self._shown[store_id]
        self._call(lambda: self.client.set_location(shown.location))
        if timeline is not None and value is not None:
            self._set_time(store_id, timeline, value)
        graph: dict[str, Any] = self._call(lambda: self.client.get_transform_graph(store_id))
        return graph

    def close(self) -> None:
        """End the viewer (SIGTERM to its session, SIGKILL after 5 s) with Ctrl-C and SIGTERM held off meanwhile."""
        process, self._process = self._process, None
        with held_off():
            shown, self._shown = list(self._shown.values()), {}
            try:
                for recording in shown:
                    recording.stream.disconnect()
            finally:
                if process is not None:
                    stop_session(process)
                shutil.rmtree(self._folder, ignore_errors=True)
        atexit.unregister(self.close)


def write_png(path: Path, png: bytes) -> None:
    """Whole or not at all: a partial file beside it, renamed over it (removed if anything stops the write)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(f".{path.name}.partial")
    try:
        partial.write_bytes(png)
        os.replace(partial, path)
    finally:
        partial.unlink(missing_ok=True)


def _escaped(application_id: str) -> str:
    """As a StoreId spells it: a backslash and a colon in the application id are escaped."""
    return application_id.replace("\\", "\\\\").replace(":", "\\:")


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
        return port


def _start(folder: Path, log_path: Path, size: Size, port: int) -> subprocess.Popen[bytes]:
    window = f"{size.width + NOTIFICATIONS_WIDTH + CHROME[0]}x{size.height + CHROME[1]}"
    args = ["--headless", "--hide-welcome-screen", "--port", str(port), "--bind", "127.0.0.1", "--window-size", window]
    if sys.platform != "darwin":
        args += ["--renderer", "vulkan"]  # the default falls back to GL on a software rasterizer, which panics
    runtime = {} if os.environ.get("XDG_RUNTIME_DIR") else {"XDG_RUNTIME_DIR": str(folder)}
    with open(log_path, "wb") as log:
        return start_viewer(viewer_binary("draw pictures"), args, log, folder, runtime)


def _cropped(png: bytes, size: Size) -> bytes:
    """The picture at exactly `size`: the view comes out a few points wider (column shares share the separator)."""
    from PIL import Image

    with Image.open(io.BytesIO(png)) as image:
        width, height = image.size
        if (width, height) == (size.width, size.height) or width < size.width or height < size.height:
            return png
        left, top = (width - size.width) // 2, (height - size.height) // 2
        return png_bytes(image.crop((left, top, left + size.width, top + size.height)))


def png_bytes(image: object) -> bytes:
    """A Pillow image as PNG bytes."""
    buffer = io.BytesIO()
    image.save(buffer, format="PNG")  # type: ignore[attr-defined]
    return buffer.getvalue()
