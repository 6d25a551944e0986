"""A small client of Chromium's DevTools protocol, for the browser tests: Debian's `chromium`, headless, driven over
one WebSocket (websocket-client). Nothing here downloads a browser: without `chromium` on PATH the tests skip.

One `Browser` is one chromium process (its own temporary profile, `--remote-debugging-port=0`: the port it took is
read from the `DevToolsActivePort` file it writes there). `Browser.page()` opens a tab and attaches to it with a flat
session; a `Page` records every console message, exception and network request of its tab, so a test asserts on what
the page did without racing it.
"""

from __future__ import annotations

import base64
import itertools
import json
import os
import shutil
import signal
import subprocess
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import websocket

from urdf_pipeline.process.children import die_with_parent

# RERUN-0.41-FACTS.md: the flags under which Debian's chromium renders Rerun's web viewer headless with software WebGL2.
FLAGS = (
    "--headless=new",
    "--no-sandbox",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--remote-debugging-port=0",
    # nothing of the browser's own reaches out (updates, sync, field trials, safe browsing): the page's requests only
    "--no-first-run",
    "--no-default-browser-check",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-default-apps",
    "--disable-extensions",
    "--metrics-recording-only",
    "--safebrowsing-disable-auto-update",
    "--disable-features=Translate,OptimizationHints,MediaRouter,DialMediaRouteProvider",
    "--window-size=1024,768",
    "--hide-scrollbars",
    "--mute-audio",
)
STARTUP_SECONDS = 60.0
CALL_SECONDS = 120.0


class DevToolsError(RuntimeError):
    """The browser answered a call with an error, or did not answer."""


def chromium_binary() -> str | None:
    """Debian's chromium (or a chromium/google-chrome on PATH); None when there is none."""
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        found = shutil.which(name)
        if found:
            return found
    return None


@dataclass
class Request:
    """One network request of a page: its URL, and how it ended (status, or the error and the blocked reason)."""

    url: str
    status: int | None = None
    error: str | None = None
    blocked: str | None = None


@dataclass
class _Session:
    events: list[dict[str, Any]] = field(default_factory=list)


class Browser:
    """`with Browser() as browser: page = browser.page()`: one headless chromium with a temporary profile."""

    def __init__(self, binary: str | None = None) -> None:
        found = binary or chromium_binary()
        if found is None:
            raise FileNotFoundError("no chromium on PATH (apt-get install chromium; make test installs it when run as root)")
        self._profile = Path(tempfile.mkdtemp(prefix="urdf-pipeline-chromium-"))
        self._log = open(self._profile / "chromium.log", "wb")  # (closed in close())
        self._process = subprocess.Popen(
            [found, *FLAGS, f"--user-data-dir={self._profile}", "about:blank"],
            stdin=subprocess.DEVNULL,
            stdout=self._log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
            preexec_fn=die_with_parent(),  # a test session killed outright (SIGKILL, a CI timeout) takes chromium with it
        )
        self._ids = itertools.count(1)
        self._answers: dict[int, dict[str, Any]] = {}
        self._sessions: dict[str, _Session] = {}
        self._lock = threading.Condition()
        self._closed = False
        try:
            self._socket = websocket.create_connection(self._endpoint(), timeout=None, suppress_origin=True)
        except BaseException:
            self.close()
            raise
        self._reader = threading.Thread(target=self._read, name="devtools-reader", daemon=True)
        self._reader.start()

    def __enter__(self) -> Browser:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _endpoint(self) -> str:
        """ws://127.0.0.1:PORT/devtools/browser/ID, from the DevToolsActivePort file chromium writes when it listens."""
        active = self._profile / "DevToolsActivePort"
        deadline = time.monotonic() + STARTUP_SECONDS
        while time.monotonic() < deadline:
            if self._process.poll() is not None:
                raise DevToolsError(f"chromium stopped (exit status {self._process.returncode}): {self.log_tail()}")
            lines = active.read_text().split("\n") if active.exists() else []
            if len(lines) >= 2 and lines[0].strip().isdigit() and lines[1].strip():
                return f"ws://127.0.0.1:{lines[0].strip()}{lines[1].strip()}"
            time.sleep(0.05)
        raise DevToolsError(f"chromium did not open its DevTools port within {STARTUP_SECONDS:.0f} s: {self.log_tail()}")

    def log_tail(self) -> str:
        log = self._profile / "chromium.log"
        return log.read_text(errors="replace")[-2000:] if log.exists() else ""

    def _read(self) -> None:
        while True:
            try:
                message = json.loads(self._socket.recv())
            except (websocket.WebSocketException, OSError, ValueError):
                with self._lock:
                    self._closed = True
                    self._lock.notify_all()
                return
            with self._lock:
                if "id" in message:
                    self._answers[message["id"]] = message
                elif "sessionId" in message and message["sessionId"] in self._sessions:
                    self._sessions[message["sessionId"]].events.append(message)
                self._lock.notify_all()

    def call(self, method: str, params: dict[str, Any] | None = None, session: str | None = None, timeout: float = CALL_SECONDS) -> Any:
        """Send one command and wait for its answer; its `result`, or DevToolsError."""
        number = next(self._ids)
        message: dict[str, Any] = {"id": number, "method": method, "params": params or {}}
        if session is not None:
            message["sessionId"] = session
        self._socket.send(json.dumps(message))
        deadline = time.monotonic() + timeout
        with self._lock:
            while number not in self._answers:
                if self._closed:
                    raise DevToolsError(f"{method}: the browser closed the connection")
                if not self._lock.wait(max(0.0, deadline - time.monotonic())) and time.monotonic() >= deadline:
                    raise DevToolsError(f"{method}: no answer within {timeout:.0f} s")
            answer = self._answers.pop(number)
        if "error" in answer:
            raise DevToolsError(f"{method}: {answer['error']}")
        return answer.get("result", {})

    def page(self, width: int = 1024, height: int = 768) -> Page:
        """A new tab of the given viewport size, with its console, exceptions and network recorded from the start."""
        target = self.call("Target.createTarget", {"url": "about:blank"})["targetId"]
        session = self.call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        with self._lock:
            self._sessions[session] = _Session()
        page = Page(self, session, target)
        for domain in ("Page.enable", "Runtime.enable", "Network.enable", "Log.enable"):
            page.call(domain)
        page.call("Emulation.setDeviceMetricsOverride", {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False})
        return page

    def events(self, session: str) -> list[dict[str, Any]]:
        with self._lock:
            return list(self._sessions[session].events)

    def close(self) -> None:
        """Ask the browser to close, then end its process group; remove the profile."""
        process = getattr(self, "_process", None)
        socket = getattr(self, "_socket", None)
        if socket is not None:
            try:
                self.call("Browser.close", timeout=5)
            except (DevToolsError, websocket.WebSocketException, OSError):
                pass
            socket.close()
        if process is not None and process.poll() is None:
            for sent in (signal.SIGTERM, signal.SIGKILL):
                try:
                    os.killpg(process.pid, sent)
                except ProcessLookupError:
                    break
                try:
                    process.wait(5)
                    break
                except subprocess.TimeoutExpired:
                    continue
        self._log.close()
        shutil.rmtree(self._profile, ignore_errors=True)


class Page:
    """One tab: navigate, evaluate, screenshot, and what it logged and requested."""

    def __init__(self, browser: Browser, session: str, target: str) -> None:
        self.browser = browser
        self.session = session
        self.target = target

    def call(self, method: str, params: dict[str, Any] | None = None, timeout: float = CALL_SECONDS) -> Any:
        return self.browser.call(method, params, self.session, timeout)

    def navigate(self, url: str, timeout: float = 60.0) -> None:
        """Open `url` in the tab and wait for its load event (its scripts have run; the wasm may still be loading)."""
        loads = len(self.events("Page.loadEventFired"))
        answer = self.call("Page.navigate", {"url": url})
        if answer.get("errorText"):
            raise DevToolsError(f"cannot open {url}: {answer['errorText']}")
        self.wait_for(lambda: len(self.events("Page.loadEventFired")) > loads, timeout, f"the load of {url}", poll=0.05)

    def evaluate(self, expression: str) -> Any:
        """The expression's value (awaited when it is a promise), or DevToolsError with the exception it threw."""
        answer = self.call("Runtime.evaluate", {"expression": expression, "returnByValue": True, "awaitPromise": True})
        if "exceptionDetails" in answer:
            raise DevToolsError(f"{expression}: {answer['exceptionDetails']}")
        return answer["result"].get("value")

    def screenshot(self) -> bytes:
        return base64.b64decode(self.call("Page.captureScreenshot", {"format": "png"})["data"])

    def wait_for(self, condition: Callable[[], Any], timeout: float, what: str, poll: float = 0.5) -> Any:
        """`condition()`'s first truthy value, polled until `timeout` seconds have passed (then AssertionError)."""
        deadline = time.monotonic() + timeout
        while True:
            value = condition()
            if value:
                return value
            if time.monotonic() > deadline:
                raise AssertionError(f"{what}: not within {timeout:.0f} s")
            time.sleep(poll)

    def events(self, *methods: str) -> list[dict[str, Any]]:
        return [event for event in self.browser.events(self.session) if not methods or event["method"] in methods]

    def console_errors(self) -> list[str]:
        """Every error the page logged: console.error, uncaught exceptions, and the browser's own error entries
        (a blocked request, a Content-Security-Policy violation)."""
        errors = []
        for event in self.events("Runtime.consoleAPICalled", "Runtime.exceptionThrown", "Log.entryAdded"):
            params = event["params"]
            if event["method"] == "Runtime.consoleAPICalled" and params["type"] in ("error", "assert"):
                errors.append(" ".join(str(arg.get("value", arg.get("description", ""))) for arg in params["args"]))
            elif event["method"] == "Runtime.exceptionThrown":
                details = params["exceptionDetails"]
                errors.append(str(details.get("exception", {}).get("description", details.get("text"))))
            elif event["method"] == "Log.entryAdded" and params["entry"]["level"] == "error":
                errors.append(f"{params['entry']['source']}: {params['entry']['text']} {params['entry'].get('url', '')}")
        return errors

    def console(self) -> list[str]:
        """Every console message, as `type: text`."""
        return [
            f"{e['params']['type']}: " + " ".join(str(a.get("value", a.get("description", ""))) for a in e["params"]["args"])
            for e in self.events("Runtime.consoleAPICalled")
        ]

    def requests(self) -> list[Request]:
        """Every request the page made (also those the browser blocked), in order, with how each ended."""
        found: dict[str, Request] = {}
        for event in self.events("Network.requestWillBeSent", "Network.responseReceived", "Network.loadingFailed"):
            params = event["params"]
            if event["method"] == "Network.requestWillBeSent":
                found[params["requestId"]] = Request(params["request"]["url"])
            elif params["requestId"] in found:
                request = found[params["requestId"]]
                if event["method"] == "Network.responseReceived":
                    request.status = params["response"]["status"]
                else:
                    request.error = params.get("errorText")
                    request.blocked = params.get("blockedReason") or params.get("corsErrorStatus", {}).get("corsError")
        return list(found.values())

    def viewer_state(self) -> bytes:
        """The state of the Rerun viewer in the tab's first frame (the Viewer Control API's GetStateResponse,
        protobuf: its recordings, their timelines, its views), from the frame's WebHandle, read in the frame's own
        JavaScript context (the viewer's `wasm_bindgen` is no property of the window)."""
        tree = self.call("Page.getFrameTree")["frameTree"]
        frame = tree["childFrames"][0]["frame"]["id"]
        contexts = [e["params"]["context"] for e in self.events("Runtime.executionContextCreated")]
        context = [c["id"] for c in contexts if c.get("auxData", {}).get("frameId") == frame and c["auxData"].get("isDefault")][-1]
        prototype = self.call("Runtime.evaluate", {"expression": "wasm_bindgen.WebHandle.prototype", "contextId": context})["result"]
        handles = self.call("Runtime.queryObjects", {"prototypeObjectId": prototype["objectId"]})["objects"]
        answer = self.call(
            "Runtime.callFunctionOn",
            {
                "objectId": handles["objectId"],
                "functionDeclaration": "function () { return Array.from(this[0].viewer_state()); }",
                "returnByValue": True,
            },
        )
        return bytes(answer["result"]["value"])

    def close(self) -> None:
        self.browser.call("Target.closeTarget", {"targetId": self.target})


def site_paths(requests: list[Request], prefix: str) -> set[str]:
    """The site paths the page asked for, once it is checked that every request went to 127.0.0.1, stayed under the
    site's folder `prefix` and was answered (none blocked): a page of ours asks nothing of anyone else."""
    elsewhere = [r.url for r in requests if urlsplit(r.url).hostname != "127.0.0.1"]
    assert elsewhere == [], f"requests to other hosts: {elsewhere}"
    outside = [r.url for r in requests if not urlsplit(r.url).path.startswith(f"/{prefix}/")]
    assert outside == [], f"requests outside the site's folder: {outside}"
    failed = [r for r in requests if r.status not in (200, 304)]
    assert failed == [], f"requests not answered: {failed}"
    return {urlsplit(r.url).path.removeprefix(f"/{prefix}/") for r in requests}
