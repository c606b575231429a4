"""Headless Chromium looking at a Rerun web viewer: what the browser tests and `make bench` share.

The viewer draws everything on one WebGL canvas, so the DOM says nothing. What it shows is read
from the viewer itself: the page's `WebHandle.viewer_state()` is the Viewer Control API's
`GetViewerStateResponse` (rerun/v1alpha1/viewer_control.proto): the active recording, its
timelines with their ranges, and every view of the blueprint with its warnings and errors.
Screenshots tell whether something is drawn.

    with served_trace(Path("out/run/trace.rrd"), "overview") as served, ViewerPage(served) as viewer:
        viewer.wait_for(lambda state: bool(state.views), "the overview's views")
        viewer.show_dashboard("tuning")                   # same page, same viewer process
        image = viewer.screenshot(Path("out/tuning.png"))

    check_dashboards(Path("out/run/trace.rrd"), ["overview", "tuning"], Path("out/viewer"))
    time_to_first_frame(Path("out/run/trace.rrd"), "overview")   # seconds

Chromium is Debian's (`apt-get install chromium`, tools/deps), driven by Playwright (the dev
lock, requirements.lock: not a dependency of the hilrig wheel). Both are imported only when a
page is opened, so `import hilrig.observe.browser` needs neither.
"""

from __future__ import annotations

import contextlib
import os
import socket
import subprocess
import tempfile
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Self

from hilrig.observe.blueprints import dashboards, load_blueprint
from hilrig.observe.paths import CYCLE_TIMELINE
from hilrig.observe.viewer import ViewerProcess, open_trace, send_to_viewer
from hilrig.observe.viewer import wait_until_listening as viewer_wait_until_listening

if TYPE_CHECKING:
    import rerun.blueprint as rrb
    from PIL.Image import Image
    from playwright.sync_api import Browser, Page, Playwright, ViewportSize

CHROMIUM = Path("/usr/bin/chromium")
# Software rendering, no GPU and no display. Root needs --no-sandbox; /dev/shm may be tiny.
CHROMIUM_FLAGS = ["--headless=new", "--no-sandbox", "--disable-dev-shm-usage"]
MESA_EGL = Path("/usr/share/glvnd/egl_vendor.d/50_mesa.json")
"""Mesa's EGL (libegl-mesa0, tools/deps): without a GPU it renders with llvmpipe."""
RENDERER_FLAGS = {
    # WebGL through ANGLE on Mesa's EGL: llvmpipe, which Chromium keeps off its list for WebGL 2
    # unless told; it paints the same pages for less CPU than SwiftShader.
    "llvmpipe": ["--use-angle=gl-egl", "--ignore-gpu-blocklist"],
    # Chromium's own software Vulkan, asked for by name (it is retiring its silent fallback).
    "swiftshader": ["--use-angle=swiftshader", "--enable-unsafe-swiftshader"],
}
RENDERER_VARIABLE = "HIL_VIEWER_RENDERER"


def renderer() -> str:
    """Which software renderer the browser's WebGL runs on: $HIL_VIEWER_RENDERER if set (a key
    of RENDERER_FLAGS), else llvmpipe where Mesa's EGL is installed, else SwiftShader."""
    chosen = os.environ.get(RENDERER_VARIABLE)
    if chosen:
        if chosen not in RENDERER_FLAGS:
            raise BrowserUnavailableError(
                f"{RENDERER_VARIABLE}={chosen}: expected one of {', '.join(RENDERER_FLAGS)}"
            )
        return chosen
    return "llvmpipe" if MESA_EGL.exists() else "swiftshader"


def chromium_flags() -> list[str]:
    return [*CHROMIUM_FLAGS, *RENDERER_FLAGS[renderer()]]


VIEWPORT: ViewportSize = {"width": 1600, "height": 1000}
WAIT_S = 300.0  # per wait, a hang guard: the viewer renders in software, beside the unit stage's other jobs
POLL_S = 0.25
RERUN_VERSION = "0.41.0"
"""The viewer version whose viewer_control.proto `ViewerState.decode` follows."""

# The viewer's page keeps its WebHandle in a local variable. index.html calls has_panicked() on
# it every second, so wrapping that method hands us the instance, however late we wrap it.
CAPTURE_HANDLE = """() => {
    const proto = wasm_bindgen.WebHandle.prototype;
    const hasPanicked = proto.has_panicked;
    proto.has_panicked = function () { window.hilrigViewer = this; return hasPanicked.call(this); };
}"""

WEBGL_RENDERER = """() => {
    const gl = document.createElement('canvas').getContext('webgl2');
    if (!gl) return 'no WebGL 2';
    const info = gl.getExtension('WEBGL_debug_renderer_info');
    return info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);
}"""

BLUEPRINT_AREA = (204, 40, 1296, 848)
"""(left, top, right, bottom) in VIEWPORT pixels: where the blueprint's views are, between the
blueprint tree (left, 200 px), the selection panel (right, 300 px), the top bar and the time
panel (bottom, 150 px). The panels keep their pixel sizes whatever the layout inside."""
SETTLE_POLL_S = 0.5
"""Between two screenshots compared for a picture that holds still."""


def _views_box(image: Image) -> tuple[int, int, int, int]:
    """The part of a screenshot with the dashboard's views: without the top bar (its latency
    counter ticks), the side panels and the time panel."""
    width, height = image.size
    return (width * 13 // 100, height * 4 // 100, width * 81 // 100, height * 85 // 100)


PLOTTED_PIXELS = 1000
"""`plotted_pixels` above which something is plotted: at VIEWPORT, dashboards' views laid out
over a recording that none of them plots paint none, and the sparsest real one (the faults
dashboard over the fake-node trace of rig/tests/test_web_viewer.py, which checks both) paints
several times this in series lines, legend dots and coloured log levels."""


class BrowserUnavailableError(RuntimeError):
    """Playwright or Chromium is not installed: the message says what to install."""


class ViewerCheckError(AssertionError):
    """The viewer did not show what was waited for in time (an AssertionError, so pytest shows
    it as the failed expectation it is)."""


def browser_missing() -> str | None:
    """Why no headless Chromium can be driven here, in one line; None when it can."""
    try:
        import PIL  # noqa: F401
        import playwright.sync_api  # noqa: F401
    except ImportError as error:
        top = (error.name or "playwright").split(".")[0]
        package = {"PIL": "pillow"}.get(top, top)
        return (
            f"{package} is not installed: it is in the dev lock "
            "(.venv/bin/pip install -r requirements.lock, or tools/deps)"
        )
    if not CHROMIUM.exists():
        return f"no {CHROMIUM}: apt-get install chromium (tools/deps)"
    return None


def require_browser() -> None:
    reason = browser_missing()
    if reason is not None:
        raise BrowserUnavailableError(reason)


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
    """The parts of `GetViewerStateResponse` the checks look at."""

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

    @property
    def recording_id(self) -> str | None:
        """The active recording's id: its store id is `Recording:<application id>:<recording id>`."""
        kind, _, rest = self.active_recording.partition(":")
        application, _, recording = rest.partition(":")
        return recording if kind == "Recording" and application and recording else None

    def shown_views(self) -> set[tuple[str, str]]:
        return {(view.name, view.origin) for view in self.views}

    def view_errors(self) -> list[tuple[str, tuple[str, str]]]:
        return [(view.name, report) for view in self.views for report in view.reports if report[0] == "error"]


def dashboard_views(blueprint: str | rrb.Blueprint) -> set[tuple[str, str]]:
    """(name, origin) of every view of a blueprint (a dashboard's name, or a blueprint)."""
    dashboards()  # importable from a checkout on PYTHONPATH alone too
    from hilrig.observe.dashboard_check import views

    shown = load_blueprint(blueprint) if isinstance(blueprint, str) else blueprint
    return {(view.name, str(view.origin)) for view in views(shown)}


# --- Ports and the viewer process --------------------------------------------------------------
def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def wait_until_listening(port: int, process: subprocess.Popen[Any], timeout_s: float = WAIT_S) -> None:
    """`hilrig.observe.viewer.wait_until_listening`, its failure a ViewerCheckError."""
    try:
        viewer_wait_until_listening(port, process, timeout_s)
    except OSError as error:
        raise ViewerCheckError(str(error)) from None


@dataclass(frozen=True)
class ServedTrace:
    """A trace served to the web viewer: the page to open and the gRPC port its data comes from
    (where another blueprint can be sent)."""

    url: str
    grpc_port: int
    process: ViewerProcess


@contextlib.contextmanager
def served_trace(trace: Path, dashboard: str) -> Iterator[ServedTrace]:
    """`open_trace(trace, dashboard, web=True)` on free ports, both listening; on exit the whole
    viewer process group (the wrapper and the rerun binary) is terminated."""
    web_port, grpc_port = free_port(), free_port()
    process = open_trace(trace, dashboard, web=True, web_port=web_port, grpc_port=grpc_port)
    assert isinstance(process, ViewerProcess) and process.url is not None
    try:
        wait_until_listening(web_port, process)  # open_trace waited for the gRPC port
        yield ServedTrace(process.url, grpc_port, process)
    finally:
        process.terminate()
        try:
            process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


def show_dashboard(grpc_port: int, recording_id: str, dashboard: str | rrb.Blueprint) -> None:
    """Make `dashboard` the active blueprint of a running viewer (`send_to_viewer`). The stream
    takes the shown recording's id: a stream of another id would be a new, empty recording that
    the viewer then makes the active one."""
    blueprint = load_blueprint(dashboard) if isinstance(dashboard, str) else dashboard
    send_to_viewer(grpc_port, blueprint, recording_id=recording_id)


# --- The page ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class ConsoleLine:
    type: str  # "log", "warning", "error", "debug", ...
    text: str
    url: str  # where it came from, "" when the browser does not say


def is_fatal(line: ConsoleLine) -> bool:
    """An error that means the viewer failed, as opposed to this machine being offline (the page
    asks the internet for fonts and for the welcome screen's example list)."""
    text = line.text
    if "ERROR " in text or "panicked" in text or "Rerun has crashed" in text:
        return True  # the viewer's own error log, a Rust panic
    if line.type != "error":
        return False
    if text.startswith("Failed to load resource"):
        return line.url.startswith("http://127.0.0.1")
    return not text.startswith("TypeError: Failed to fetch")


UI_ACCENT_HUE = 215.0
"""Hue (degrees) of the viewer's selection blue, rgb(24, 106, 221): the highlighted timeline
column of every text log view is in it (about 550 pixels), drawn or not."""


def saturated_pixels(image: Image, box: tuple[int, int, int, int]) -> int:
    """Pixels inside `box` of clear colour (HSV saturation above 0.4, value above 0.3), other
    than the viewer's own accent (within 4 degrees of UI_ACCENT_HUE): the UI itself is greys and
    white. Counted with numpy: a screenshot has a million pixels."""
    import numpy as np

    rgb = np.asarray(image.convert("RGB").crop(box), dtype=np.float32) / 255
    value = rgb.max(axis=2)
    chroma = value - rgb.min(axis=2)
    clear = rgb[(value > 0.3) & (chroma > 0.4 * value)]
    red, green, blue = clear[:, 0], clear[:, 1], clear[:, 2]
    top, span = clear.max(axis=1), np.ptp(clear, axis=1)
    # The hexcone hue, in the sextant of whichever channel is largest.
    hue = np.where(
        top == red,
        60 * ((green - blue) / span % 6),
        np.where(top == green, 60 * ((blue - red) / span + 2), 60 * ((red - green) / span + 4)),
    )
    return int(np.count_nonzero(np.abs(hue - UI_ACCENT_HUE) > 4))


def plotted_pixels(image: Image) -> int:
    """Saturated pixels among the blueprint's views, whatever their layout (PLOTTED_PIXELS)."""
    return saturated_pixels(image, BLUEPRINT_AREA)


class ViewerPage:
    """Headless Chromium showing one viewer page, with the viewer's WebHandle captured and the
    browser's console and page errors collected from the start.

    `ViewerPage(served)` opens a served trace (and can switch its dashboard); `ViewerPage(url,
    server_check=...)` keeps trying a page that is still coming up, calling `server_check` (which
    raises when the server is gone) between attempts.
    """

    def __init__(
        self,
        target: ServedTrace | str,
        *,
        server_check: Callable[[], None] | None = None,
        viewport: ViewportSize = VIEWPORT,
        wait_s: float = WAIT_S,
    ) -> None:
        url = target.url if isinstance(target, ServedTrace) else target
        # renderer=webgl: headless Chromium has no WebGPU adapter here; asking skips the probe.
        self.url = f"{url}&renderer=webgl"
        self.grpc_port = target.grpc_port if isinstance(target, ServedTrace) else None
        self.server_check = server_check
        self.viewport = viewport
        self.wait_s = wait_s
        self.console: list[ConsoleLine] = []
        self.page_errors: list[str] = []
        self.opened_at = 0.0  # time.monotonic() when the page was asked for
        self._playwright: Playwright | None = None
        self._browser: Browser | None = None
        self._page: Page | None = None

    def __enter__(self) -> Self:
        require_browser()
        from playwright.sync_api import sync_playwright

        self._playwright = sync_playwright().start()
        try:
            self._browser = self._playwright.chromium.launch(
                executable_path=str(CHROMIUM), args=chromium_flags(), timeout=self.wait_s * 1000
            )
            page = self._page = self._browser.new_page(viewport=self.viewport)
            page.set_default_timeout(self.wait_s * 1000)
            page.on("console", self._on_console)
            page.on("pageerror", lambda error: self.page_errors.append(str(error)))
            self._open(page)
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        if self._browser is not None:
            self._browser.close()
            self._browser = None
        if self._playwright is not None:
            self._playwright.stop()
            self._playwright = None
        self._page = None

    def _on_console(self, message: Any) -> None:
        self.console.append(ConsoleLine(message.type, message.text, message.location.get("url", "")))

    def _open(self, page: Page) -> None:
        from playwright.sync_api import Error

        self.opened_at = time.monotonic()
        deadline = self.opened_at + self.wait_s
        while True:
            try:
                # Not "load": that waits for the web fonts, which an offline machine never gets.
                page.goto(self.url, wait_until="domcontentloaded")
                break
            except Error:
                if self.server_check is None:
                    raise
                self.server_check()
                if time.monotonic() > deadline:
                    raise ViewerCheckError(
                        f"nothing served at {self.url} within {self.wait_s:.0f} s"
                    ) from None
                page.wait_for_timeout(1000)
        page.evaluate(CAPTURE_HANDLE)
        page.wait_for_function("() => window.hilrigViewer !== undefined")

    @property
    def page(self) -> Page:
        if self._page is None:
            raise RuntimeError("the ViewerPage is not open (use it in a with statement)")
        return self._page

    def resize(self, viewport: ViewportSize) -> None:
        """The page at `viewport` from now on (the viewer lays itself out again)."""
        if self.page.viewport_size != viewport:
            self.page.set_viewport_size(viewport)

    # --- what the viewer says -------------------------------------------------------------
    def state(self) -> ViewerState:
        data = self.page.evaluate("() => Array.from(window.hilrigViewer.viewer_state())")
        return ViewerState.decode(bytes(data))

    def wait_for(
        self, ready: Callable[[ViewerState], bool], what: str, poll_s: float = POLL_S
    ) -> ViewerState:
        """Poll the viewer's state until `ready` holds (Expected ..., but got the last answer)."""
        from playwright.sync_api import Error

        deadline = time.monotonic() + self.wait_s
        while True:
            try:
                state: ViewerState | str = self.state()
            except Error as error:
                if "ViewerControlError" not in error.message:
                    raise
                state = error.message.splitlines()[0]  # "not running, or is busy painting a frame": retry
            if isinstance(state, ViewerState) and ready(state):
                return state
            if time.monotonic() > deadline:
                raise ViewerCheckError(
                    f"Expected {what} within {self.wait_s:.0f} s, but the viewer answers {state}"
                )
            self.page.wait_for_timeout(poll_s * 1000)  # lets Playwright deliver console events meanwhile

    def webgl_renderer(self) -> str:
        """The renderer this page's WebGL 2 runs on, as WebGL names it ("ANGLE (Mesa/X.org,
        llvmpipe ...)"), or "no WebGL 2"."""
        return str(self.page.evaluate(WEBGL_RENDERER))

    def has_panicked(self) -> bool:
        return bool(self.page.evaluate("() => window.hilrigViewer.has_panicked()"))

    def fatal_console(self, since: int = 0) -> list[str]:
        """The console errors that mean the viewer failed (`is_fatal`), from line `since` on."""
        return [line.text for line in self.console[since:] if is_fatal(line)]

    def write_console_log(self, path: Path) -> None:
        # Without the debug level (shader sources, tens of thousands of lines).
        path.write_text(
            "".join(f"{line.type}: {line.text}\n" for line in self.console if line.type != "debug")
        )

    # --- what it draws --------------------------------------------------------------------
    def screenshot(self, path: Path) -> Image:
        from PIL import Image

        path.parent.mkdir(parents=True, exist_ok=True)
        self.page.screenshot(path=str(path))
        return Image.open(path).convert("RGB")

    def screenshot_until_plotted(self, path: Path) -> tuple[Image, int]:
        """Screenshots until something is plotted and the picture holds still (the state can be
        a frame ahead of the canvas, and a plot fits its axes to the data over a few frames after
        the first curve is drawn: taken then, curves leave the plot): the last one and its
        `plotted_pixels`, which stay below PLOTTED_PIXELS if time ran out."""
        deadline = time.monotonic() + self.wait_s
        previous: bytes | None = None
        while True:
            image = self.screenshot(path)
            plotted = plotted_pixels(image)
            pixels = image.crop(_views_box(image)).tobytes()
            if (plotted > PLOTTED_PIXELS and pixels == previous) or time.monotonic() > deadline:
                return image, plotted
            previous = pixels
            time.sleep(SETTLE_POLL_S)

    # --- switching dashboards ---------------------------------------------------------------
    def show_dashboard(
        self, dashboard: str | rrb.Blueprint, timeline_ends: dict[str, int] | None = None
    ) -> ViewerState:
        """Send `dashboard` to this page's viewer and wait until it shows exactly its views (and,
        if given, the recording up to `timeline_ends`). Only for a page of a `ServedTrace`."""
        if self.grpc_port is None:
            raise RuntimeError("show_dashboard needs the gRPC port: open the page with a ServedTrace")
        # The recording with data: the stream that served the trace is a recording of its own
        # (no rows), which a page can show active for a moment before the trace's.
        recording = self.wait_for(
            lambda s: s.recording_id is not None and bool(s.timeline_ends), "an active recording with data"
        ).recording_id
        assert recording is not None
        expected = dashboard_views(dashboard)
        name = dashboard if isinstance(dashboard, str) else "the blueprint"
        show_dashboard(self.grpc_port, recording, dashboard)
        return self.wait_for(
            lambda s: (
                s.shown_views() == expected and s.recording_id == recording and _whole(s, timeline_ends)
            ),
            f"the views of {name!r} on recording {recording!r}",
        )


def _whole(state: ViewerState, timeline_ends: dict[str, int] | None) -> bool:
    """The recording is there whole: each timeline at its end and nothing left loading (a
    timeline reaches its end with the first chunk that holds the last cycle, while other
    entities' rows still stream in). None: not waited for."""
    if timeline_ends is None:
        return True
    at_end = all(state.timeline_ends.get(t) == end for t, end in timeline_ends.items())
    return at_end and not state.loading


# --- Checking dashboards on a trace ------------------------------------------------------------
@dataclass(frozen=True)
class DashboardShown:
    """What the viewer showed of one dashboard over a trace."""

    name: str
    state: ViewerState
    expected_views: frozenset[tuple[str, str]]
    fatal_console: tuple[str, ...]
    page_errors: tuple[str, ...]
    plotted_pixels: int
    screenshot: Path

    def problems(self) -> list[str]:
        """Everything that is not as it should be; empty when the dashboard is shown whole."""
        state = self.state
        found = []
        if state.version != RERUN_VERSION:
            found.append(f"the viewer is rerun {state.version}: the state is decoded as {RERUN_VERSION}'s")
        if state.shown_views() != self.expected_views:
            found.append(f"views {sorted(state.shown_views())}, expected {sorted(self.expected_views)}")
        hidden = [view.name for view in state.views if not view.visible]
        if hidden:
            found.append(f"hidden views: {hidden}")
        if state.view_errors():
            found.append(f"views reporting errors: {state.view_errors()}")
        if state.loading:
            found.append(f"still loading: {state.loading}")
        if self.fatal_console:
            found.append(f"console errors: {list(self.fatal_console)}")
        if self.page_errors:
            found.append(f"page errors: {list(self.page_errors)}")
        if self.plotted_pixels <= PLOTTED_PIXELS:
            found.append(
                f"{self.screenshot}: only {self.plotted_pixels} plotted pixels (<= {PLOTTED_PIXELS})"
            )
        return found


def last_cycle(trace: Path) -> int | None:
    """The last cycle a trace logged (None: no cycle timeline, e.g. a bus recording)."""
    from hilrig.observe.reader import timeline_end

    return timeline_end(trace, CYCLE_TIMELINE)


def check_dashboards(
    trace: Path, names: Iterable[str], out_dir: Path, *, viewer: ViewerPage | None = None
) -> dict[str, DashboardShown]:
    """Show each dashboard over `trace`, one after another in one page of one viewer process
    (the first served with it, the rest sent to it), each once the recording is there whole;
    a screenshot of each to out_dir/<name>.png. `viewer`: a page already open on the trace,
    served with the first name (its console is the caller's to look at too)."""
    names = list(names)
    if not names:
        return {}
    end = last_cycle(trace)
    whole = {CYCLE_TIMELINE: end} if end is not None else None
    out_dir.mkdir(parents=True, exist_ok=True)
    with contextlib.ExitStack() as stack:
        if viewer is None:
            served = stack.enter_context(served_trace(trace, names[0]))
            viewer = stack.enter_context(ViewerPage(served))
        viewer.resize(viewer.viewport)  # as the user sees them, whatever a check before needed
        shown: dict[str, DashboardShown] = {}
        for number, name in enumerate(names):
            console_from, errors_from = len(viewer.console), len(viewer.page_errors)
            expected = dashboard_views(name)
            if number == 0:
                viewer.wait_for(
                    lambda s, expected=expected: s.shown_views() == expected and _whole(s, whole),
                    f"the views of {name!r} over the whole recording",
                )
                console_from = errors_from = 0  # the page's start is the first dashboard's
            else:
                viewer.show_dashboard(name, whole)
            screenshot = out_dir / f"{name}.png"
            _, plotted = viewer.screenshot_until_plotted(screenshot)
            shown[name] = DashboardShown(
                name=name,
                state=viewer.state(),  # as of the frame the screenshot shows, or after it
                expected_views=frozenset(expected),
                fatal_console=tuple(viewer.fatal_console(console_from)),
                page_errors=tuple(viewer.page_errors[errors_from:]),
                plotted_pixels=plotted,
                screenshot=screenshot,
            )
    return shown


def time_to_first_frame(trace: Path, dashboard: str = "overview", screenshot: Path | None = None) -> float:
    """Seconds from asking Chromium for the viewer page (browser already started, trace served)
    to the first screenshot of the recording whole (the cycle timeline at the last cycle logged,
    nothing left loading) with something plotted. Raises ViewerCheckError if that does not come
    within WAIT_S per wait."""
    end = last_cycle(trace)
    if end is None:
        raise ValueError(f"{trace}: no {CYCLE_TIMELINE!r} timeline to know the recording's end by")
    with served_trace(trace, dashboard) as served, contextlib.ExitStack() as stack:
        viewer = stack.enter_context(ViewerPage(served))
        viewer.wait_for(
            lambda s: _whole(s, {CYCLE_TIMELINE: end}) and bool(s.views),
            f"the recording up to cycle {end} in {dashboard!r}",
            poll_s=0.05,
        )
        if screenshot is None:
            folder = stack.enter_context(tempfile.TemporaryDirectory(prefix="hilrig-first-frame-"))
            screenshot = Path(folder) / "first-frame.png"
        _, plotted = viewer.screenshot_until_plotted(screenshot)
        drawn_at = time.monotonic()
        if plotted <= PLOTTED_PIXELS:
            raise ViewerCheckError(f"{dashboard!r} drew only {plotted} plotted pixels within {WAIT_S:.0f} s")
        return drawn_at - viewer.opened_at


__all__ = [
    "BLUEPRINT_AREA",
    "CAPTURE_HANDLE",
    "CHROMIUM",
    "CHROMIUM_FLAGS",
    "MESA_EGL",
    "PLOTTED_PIXELS",
    "RENDERER_FLAGS",
    "RENDERER_VARIABLE",
    "RERUN_VERSION",
    "VIEWPORT",
    "WAIT_S",
    "WEBGL_RENDERER",
    "BrowserUnavailableError",
    "ConsoleLine",
    "DashboardShown",
    "ServedTrace",
    "ShownView",
    "ViewerCheckError",
    "ViewerPage",
    "ViewerState",
    "browser_missing",
    "check_dashboards",
    "chromium_flags",
    "dashboard_views",
    "free_port",
    "is_fatal",
    "last_cycle",
    "plotted_pixels",
    "renderer",
    "require_browser",
    "served_trace",
    "show_dashboard",
    "time_to_first_frame",
    "wait_until_listening",
]
