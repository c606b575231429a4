"""The web viewer, served by `open_trace(..., web=True)`, shows a recording with its blueprint in
headless Chromium (Debian's `chromium`, driven by Playwright; no browser is downloaded).

The viewer draws everything on one WebGL canvas, so the DOM says nothing. What it shows is read
from the viewer itself: the page's `WebHandle.viewer_state()` is the Viewer Control API's
`GetViewerStateResponse` (rerun/v1alpha1/viewer_control.proto): the active recording, its
timelines with their ranges, and every view of the blueprint with its warnings and errors. The
test waits on that, then takes a screenshot to $HIL_OUT_DIR/viewer/screenshot.png (default
out/viewer/) beside the browser's console log, and checks the pixels are a drawn viewer.

    .venv/bin/python -m pytest rig/tests/test_web_viewer.py -p no:cacheprovider
"""

from __future__ import annotations

import colorsys
import os
import socket
import subprocess
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import can
import pytest
from PIL import Image
from playwright.sync_api import ConsoleMessage, Error, Page, ViewportSize, sync_playwright

from hilrig.fake_node import FakeJointNode
from hilrig.physics import JointParams
from hilrig.rig import Rig
from hilrig.table import BOARD_TABLE, EmcyCode, RigTable
from hilrig.trace import (
    APPLICATION_ID,
    CYCLE_TIMELINE,
    SIM_TIME_TIMELINE,
    Tracer,
    TraceSink,
    ViewerProcess,
    load_blueprint,
    open_trace,
)

REPO = Path(__file__).resolve().parents[2]
CHROMIUM = Path("/usr/bin/chromium")
# Software rendering, no GPU and no display: WebGL through ANGLE on SwiftShader, asked for by name
# (Chromium is retiring its silent fallback to it). Root needs --no-sandbox; /dev/shm may be tiny.
CHROMIUM_FLAGS = [
    "--headless=new",
    "--no-sandbox",
    "--disable-dev-shm-usage",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
]
VIEWPORT: ViewportSize = {"width": 1600, "height": 1000}
BLUEPRINT = "overview"
CYCLES = 400  # 0.4 s at 1 kHz: every plot has a step and a transient in it
WAIT_S = 120.0  # per wait; generous, the viewer renders in software on a busy machine

# The viewer's page keeps its WebHandle in a local variable. index.html calls has_panicked() on
# it every second, so wrapping that method hands us the instance, however late we wrap it.
CAPTURE_HANDLE = """() => {
    const proto = wasm_bindgen.WebHandle.prototype;
    const hasPanicked = proto.has_panicked;
    proto.has_panicked = function () { window.hilrigViewer = this; return hasPanicked.call(this); };
}"""
PLOTTED_PIXELS = 1000  # coloured pixels in the grid of plots: about 3000 when they are drawn


def output_dir() -> Path:
    path = Path(os.environ.get("HIL_OUT_DIR", REPO / "out")) / "viewer"
    path.mkdir(parents=True, exist_ok=True)
    return path


# --- The viewer's state (protobuf wire format, decoded without a schema library) --------------
def _fields(data: bytes) -> dict[int, list[int | bytes]]:
    """One protobuf message: field number -> its values (varints as int, the rest as bytes)."""
    fields: dict[int, list[int | bytes]] = {}
    at = 0

    def varint() -> int:
        nonlocal at
        value = shift = 0
        while True:
            byte = data[at]
            at += 1
            value |= (byte & 0x7F) << shift
            shift += 7
            if byte < 0x80:  # protocol-literal: protobuf varint continuation bit, not a COB-ID
                return value

    while at < len(data):
        key = varint()
        wire_type = key & 7
        value: int | bytes
        if wire_type == 0:
            value = varint()
        elif wire_type == 2:
            size = varint()
            value, at = data[at : at + size], at + size
        elif wire_type in (1, 5):
            size = 8 if wire_type == 1 else 4
            value, at = data[at : at + size], at + size
        else:
            raise ValueError(f"protobuf wire type {wire_type} at byte {at}")
        fields.setdefault(key >> 3, []).append(value)
    return fields


def _messages(fields: dict[int, list[int | bytes]], number: int) -> list[dict[int, list[int | bytes]]]:
    return [_fields(value) for value in fields.get(number, []) if isinstance(value, bytes)]


def _text(fields: dict[int, list[int | bytes]], number: int) -> str:
    values = fields.get(number, [b""])
    return values[-1].decode() if isinstance(values[-1], bytes) else str(values[-1])


def _int(fields: dict[int, list[int | bytes]], number: int) -> int:
    value = fields.get(number, [0])[-1]
    return value if isinstance(value, int) else 0


@dataclass(frozen=True)
class ShownView:
    kind: str
    name: str
    origin: str
    visible: bool
    reports: tuple[tuple[str, str], ...]  # (severity, summary)


@dataclass(frozen=True)
class ViewerState:
    """The parts of `GetViewerStateResponse` the test looks at."""

    active_recording: str
    timeline_ends: dict[str, int]  # of the active recording: last time on each timeline
    views: tuple[ShownView, ...]
    loading: tuple[str, ...]
    version: str

    @classmethod
    def decode(cls, data: bytes) -> ViewerState:
        top = _fields(data)
        active = _text(top, 2)
        ends: dict[str, int] = {}
        for recording in _messages(top, 3):
            if _text(recording, 1) != active:
                continue
            for timeline in _messages(recording, 2):
                (name,) = [_text(t, 1) for t in _messages(timeline, 1)]
                for time_range in _messages(timeline, 3):
                    ends[name] = _int(time_range, 2)
        views = tuple(
            ShownView(
                kind=_text(view, 2),
                name=_text(view, 3),
                origin=_text(view, 4),
                visible=bool(_int(view, 5)),
                reports=tuple((_text(r, 1), _text(r, 2)) for r in _messages(view, 6)),
            )
            for view in _messages(top, 5)
        )
        loading = tuple(_text(source, 1) for source in _messages(top, 7))
        return cls(active, ends, views, loading, _text(top, 6))


def read_state(page: Page) -> ViewerState:
    return ViewerState.decode(bytes(page.evaluate("() => Array.from(window.hilrigViewer.viewer_state())")))


def wait_for_state(page: Page, ready: Callable[[ViewerState], bool], what: str) -> ViewerState:
    """Poll the viewer's state until `ready` holds (Expected ..., but got the last answer)."""
    deadline = time.monotonic() + WAIT_S
    while True:
        try:
            state: ViewerState | str = read_state(page)
        except Error as error:
            if "ViewerControlError" not in error.message:
                raise
            state = error.message.splitlines()[0]  # "not running, or is busy painting a frame": retry
        if isinstance(state, ViewerState) and ready(state):
            return state
        if time.monotonic() > deadline:
            raise AssertionError(f"Expected {what} within {WAIT_S:.0f} s, but the viewer answers {state}")
        page.wait_for_timeout(250)  # lets Playwright deliver console events meanwhile


# --- Fixtures ---------------------------------------------------------------------------------
def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def wait_until_listening(port: int, process: ViewerProcess) -> None:
    deadline = time.monotonic() + WAIT_S
    while True:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=1).close()
            return
        except OSError:
            # Between attempts, wait on the viewer process itself: a viewer that dies ends the
            # wait at once instead of after a blind pause.
            try:
                returncode: int | None = process.wait(timeout=0.1)
            except subprocess.TimeoutExpired:
                returncode = None
            assert returncode is None, f"the viewer exited with {returncode} before serving port {port}"
            assert time.monotonic() < deadline, f"Expected the viewer on port {port} within {WAIT_S:.0f} s"


@pytest.fixture
def trace(tmp_path: Path) -> Path:
    """A 0.4 s run against the in-process fake node, with an SDO write and an EMCY. Recorded with no
    blueprint, so the views the viewer shows can only come from the one open_trace serves."""
    table = RigTable.load()
    path = tmp_path / "trace.rrd"
    rig_bus, fake_bus = (can.Bus(interface="virtual", channel="hilrig-web-viewer") for _ in range(2))
    fake = FakeJointNode(fake_bus, table=table)
    tracer = Tracer(TraceSink.rrd(path), table, blueprint=None, recording_name="web-viewer")
    rig = Rig(
        rig_bus, table=table, params=JointParams.fast_thermal(), seed=3, tpdo_timeout_s=0.5, tracer=tracer
    )
    fake.boot()
    try:
        rig.start()
        rig.set("velocity_setpoint", 5.0)
        rig.at(0.1, lambda r: r.set("velocity_setpoint", -2.0))
        rig.run(cycles=CYCLES // 2)
        rig.set("velocity_kp", 0.25)
        over_temperature = BOARD_TABLE.emcy("over_temperature")
        about = BOARD_TABLE.field("winding_temperature").index.to_bytes(2, "little") + bytes(3)
        fake.send_emcy(EmcyCode.OVER_TEMPERATURE, over_temperature.error_register, about)
        rig.run(cycles=CYCLES - CYCLES // 2)
    finally:
        rig.close()
        fake.close()
        tracer.close()
        rig_bus.shutdown()
        fake_bus.shutdown()
    return path


@pytest.fixture
def served(trace: Path) -> Iterator[str]:
    """The trace served by the project's own code path; yields the URL it prints."""
    web_port, grpc_port = free_port(), free_port()
    process = open_trace(trace, BLUEPRINT, web=True, web_port=web_port, grpc_port=grpc_port)
    assert not isinstance(process, list) and process.url is not None
    try:
        wait_until_listening(web_port, process)
        wait_until_listening(grpc_port, process)
        yield process.url
    finally:
        process.terminate()  # the whole process group: the wrapper and the rerun binary
        try:
            process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


# --- Console ----------------------------------------------------------------------------------
def _is_fatal(message: ConsoleMessage) -> bool:
    """An error that means the viewer failed, as opposed to this machine being offline (the page
    asks the internet for fonts and for the welcome screen's example list)."""
    text = message.text
    if "ERROR " in text or "panicked" in text or "Rerun has crashed" in text:
        return True  # the viewer's own error log, a Rust panic
    if message.type != "error":
        return False
    if text.startswith("Failed to load resource"):
        return message.location.get("url", "").startswith("http://127.0.0.1")
    return not text.startswith("TypeError: Failed to fetch")


def _expected_views() -> set[tuple[str, str]]:
    import rerun.blueprint as rrb  # slow: only when the test runs

    def walk(part: rrb.Container | rrb.View) -> Iterator[rrb.View]:
        if isinstance(part, rrb.View):
            yield part
        else:
            for child in part.contents:
                yield from walk(child)

    root = load_blueprint(BLUEPRINT).root_container
    assert root is not None
    return {(view.name, str(view.origin)) for view in walk(root)}


# --- The test ---------------------------------------------------------------------------------
@pytest.mark.skipif(not CHROMIUM.exists(), reason=f"no {CHROMIUM}: apt-get install chromium (tools/deps)")
@pytest.mark.timeout(300)
def test_web_viewer_shows_the_recording_with_its_blueprint(served: str) -> None:
    out = output_dir()
    screenshot = out / "screenshot.png"
    screenshot.unlink(missing_ok=True)
    console: list[ConsoleMessage] = []
    page_errors: list[Error] = []
    # renderer=webgl: headless Chromium has no WebGPU adapter here; asking skips the probe.
    url = f"{served}&renderer=webgl"
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(
            executable_path=str(CHROMIUM), args=CHROMIUM_FLAGS, timeout=WAIT_S * 1000
        )
        try:
            page = browser.new_page(viewport=VIEWPORT)
            page.set_default_timeout(WAIT_S * 1000)
            page.on("console", lambda message: console.append(message))
            page.on("pageerror", lambda error: page_errors.append(error))
            # Not "load": that waits for the web fonts, which an offline machine never gets.
            page.goto(url, wait_until="domcontentloaded")
            page.evaluate(CAPTURE_HANDLE)
            page.wait_for_function("() => window.hilrigViewer !== undefined")

            last_cycle = CYCLES - 1
            state = wait_for_state(
                page,
                lambda s: s.timeline_ends.get(CYCLE_TIMELINE) == last_cycle and len(s.views) > 0,
                f"recording {APPLICATION_ID} up to cycle {last_cycle} with the {BLUEPRINT!r} views",
            )
            coloured = screenshot_until_plotted(page, screenshot)
            assert not page.evaluate("() => window.hilrigViewer.has_panicked()")
        finally:
            # Without the debug level (shader sources, tens of thousands of lines).
            log = "".join(f"{m.type}: {m.text}\n" for m in console if m.type != "debug")
            (out / "console.log").write_text(log)
            browser.close()

    # The viewer shows the recording, whole, on the timeline the blueprint chose...
    assert state.active_recording.startswith(f"Recording:{APPLICATION_ID}:"), state
    assert state.version == "0.41.0", "the state decoding follows rerun 0.41's viewer_control.proto"
    assert state.timeline_ends[SIM_TIME_TIMELINE] == last_cycle * 1_000_000  # ns
    assert not state.loading, state.loading
    # ...with exactly the blueprint's views, all visible, none reporting an error.
    assert {(v.name, v.origin) for v in state.views} == _expected_views()
    assert all(v.visible for v in state.views), state.views
    errors = [(v.name, r) for v in state.views for r in v.reports if r[0] == "error"]
    assert not errors, errors
    assert not page_errors, page_errors
    fatal = [m.text for m in console if _is_fatal(m)]
    assert not fatal, f"console errors (all in {out / 'console.log'}): {fatal}"
    assert any("wgpu adapter backend: Gl" in m.text for m in console), "WebGL never came up"

    # The screenshot is a drawn viewer, not a blank canvas: the UI's text and the plots' coloured
    # lines give thousands of colours (a failed WebGL context gives one).
    image = Image.open(screenshot).convert("RGB")
    assert image.size == (VIEWPORT["width"], VIEWPORT["height"])
    colours = image.getcolors(maxcolors=1 << 24) or []
    assert len(colours) > 1000, f"{screenshot}: only {len(colours)} colours"
    assert coloured > PLOTTED_PIXELS, f"{screenshot}: the plots have only {coloured} coloured pixels"


def screenshot_until_plotted(page: Page, path: Path) -> int:
    """Screenshots until the plots show (the state can be a frame ahead of the canvas); returns
    the number of coloured pixels in the grid of plots of the last one."""
    deadline = time.monotonic() + WAIT_S
    while True:
        page.screenshot(path=str(path))
        coloured = plotted_pixels(Image.open(path).convert("RGB"))
        if coloured > PLOTTED_PIXELS or time.monotonic() > deadline:
            return coloured


def plotted_pixels(image: Image.Image) -> int:
    """Saturated pixels in the grid of plots (the blueprint's grid, left of the selection panel):
    the series lines and legend dots. With the views laid out and nothing drawn, fewer than 10."""
    width, height = image.size
    grid = image.crop((int(0.13 * width), int(0.05 * height), int(0.80 * width), int(0.68 * height)))
    return sum(count for count, rgb in grid.getcolors(1 << 24) or [] if _saturated(rgb))


def _saturated(rgb: tuple[int, int, int]) -> bool:
    _, saturation, value = colorsys.rgb_to_hsv(*(c / 255 for c in rgb))
    return saturation > 0.4 and value > 0.3
