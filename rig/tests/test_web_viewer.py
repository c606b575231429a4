"""The web viewer, served by `open_trace(..., web=True)`, shows a recording with each of the
project's dashboards in headless Chromium (Debian's `chromium`, driven by Playwright; no browser
is downloaded). The machinery is `hilrig.observe.browser`; see there how the viewer is read.

One viewer process and one page: the first dashboard is the one `open_trace` serves, every
other one is sent to the running viewer and checked in turn. A screenshot of each goes to
$HIL_OUT_DIR/viewer/<dashboard>.png (default out/viewer/), beside the browser's console log.

    .venv/bin/python -m pytest rig/tests/test_web_viewer.py -p no:cacheprovider
"""

from __future__ import annotations

import os
from pathlib import Path

import can
import pytest
from PIL import Image

from hilrig.engine.rig import Rig
from hilrig.observe import browser
from hilrig.observe.browser import (
    BLUEPRINT_AREA,
    PLOTTED_PIXELS,
    RENDERER_VARIABLE,
    RERUN_VERSION,
    VIEWPORT,
    BrowserUnavailableError,
    ConsoleLine,
    ViewerPage,
    ViewerState,
    browser_missing,
    check_dashboards,
    chromium_flags,
    dashboard_views,
    is_fatal,
    plotted_pixels,
    renderer,
    served_trace,
)
from hilrig.observe.paths import CYCLE_TIMELINE, SIM_TIME_TIMELINE
from hilrig.observe.sinks import APPLICATION_ID, TraceSink
from hilrig.observe.tracer import Tracer
from hilrig.plants import JointParams
from hilrig.session.fake_node import FakeJointNode
from hilrig.table import BOARD_TABLE, EmcyCode, RigTable

REPO = Path(__file__).resolve().parents[2]
CYCLES = 400  # 0.4 s at 1 kHz: every plot has a step and a transient in it
DASHBOARDS = ["faults", "overview"]
"""The first as served (not the trace's own overview: the served one must win), the second sent
to the running viewer; every dashboard on firmware traces is shown by tests/browser after the
bus stage (tools/run-tests stage 4)."""
NO_BROWSER = browser_missing()


def output_dir() -> Path:
    path = Path(os.environ.get("HIL_OUT_DIR", REPO / "out")) / "viewer"
    path.mkdir(parents=True, exist_ok=True)
    return path


@pytest.fixture
def trace(fake: FakeJointNode, channel: str, tmp_path: Path) -> Path:
    """A 0.4 s run against the in-process fake node, with an SDO write and an EMCY. Recorded with
    overview as its default blueprint, as `hilrig sim` records: the dashboard the viewer is
    given must still be the one it shows."""
    table = RigTable.load()
    path = tmp_path / "trace.rrd"
    tracer = Tracer(TraceSink.rrd(path), table, blueprint="overview")
    params = JointParams.fast_thermal()
    with can.Bus(interface="virtual", channel=channel) as bus:
        rig = Rig(
            bus, table=table, params=params, seed=3, tpdo_timeout_s=0.5, activity=fake.activity, tracer=tracer
        )
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
            tracer.close()
    return path


# --- In the browser ---------------------------------------------------------------------------
@pytest.mark.skipif(NO_BROWSER is not None, reason=str(NO_BROWSER))
@pytest.mark.timeout(600)
def test_web_viewer_shows_the_recording_with_every_dashboard(trace: Path) -> None:
    out = output_dir()
    for name in DASHBOARDS:
        (out / f"{name}.png").unlink(missing_ok=True)
    # Told apart by their views: a dashboard with the views of the one before would prove nothing.
    assert len({frozenset(dashboard_views(name)) for name in DASHBOARDS}) == len(DASHBOARDS)
    last_cycle = CYCLES - 1
    with served_trace(trace, DASHBOARDS[0]) as served, ViewerPage(served) as viewer:
        try:
            shown = check_dashboards(trace, DASHBOARDS, out, viewer=viewer)
            panicked = viewer.has_panicked()
            webgl = viewer.webgl_renderer()
        finally:
            viewer.write_console_log(out / "console.log")
    assert not panicked
    assert any("wgpu adapter backend: Gl" in line.text for line in viewer.console), "WebGL never came up"
    # On the renderer chosen, not on one Chromium fell back to without saying so.
    assert {"llvmpipe": "llvmpipe", "swiftshader": "SwiftShader"}[renderer()] in webgl, webgl

    assert list(shown) == DASHBOARDS
    for name, dashboard in shown.items():
        state = dashboard.state
        # The viewer shows the recording, whole, on the timeline the blueprint chose...
        assert state.active_recording.startswith(f"Recording:{APPLICATION_ID}:"), (name, state)
        assert state.version == RERUN_VERSION, "the state decoding follows rerun 0.41's viewer_control.proto"
        assert state.timeline_ends[CYCLE_TIMELINE] == last_cycle, (name, state.timeline_ends)
        assert state.timeline_ends[SIM_TIME_TIMELINE] == last_cycle * 1_000_000, name  # ns
        # ...with exactly the dashboard's views, all visible, none reporting an error, nothing
        # fatal on the console since it was sent, and plots drawn (`DashboardShown.problems`).
        assert state.shown_views() == dashboard_views(name), name
        assert dashboard.problems() == [], f"{name} (console: {out / 'console.log'})"
        # The screenshot is a drawn viewer, not a blank canvas: the UI's text and the plots'
        # coloured lines give thousands of colours (a failed WebGL context gives one).
        assert dashboard.screenshot == out / f"{name}.png"
        with Image.open(dashboard.screenshot) as image:
            assert image.size == (VIEWPORT["width"], VIEWPORT["height"])
            colours = image.convert("RGB").getcolors(maxcolors=1 << 24) or []
        assert len(colours) > 1000, f"{dashboard.screenshot}: only {len(colours)} colours"
        assert dashboard.plotted_pixels > PLOTTED_PIXELS, (
            f"{dashboard.screenshot}: {dashboard.plotted_pixels}"
        )


@pytest.fixture
def one_broken_series(tmp_path: Path) -> Path:
    """A recording of series of 200 rows each (cycle and sim_time, as the rig's): a sine, three flags
    that are all 0 (identical lines, each hiding the ones below), and one whose every value is NaN
    (it has rows, so it has data, but it draws nothing)."""
    import numpy as np
    import rerun as rr

    path = tmp_path / "broken.rrd"
    stream = rr.RecordingStream(APPLICATION_ID, recording_id="one-broken-series")
    stream.save(str(path))
    cycles = np.arange(200)
    series = [("/check/drawn", np.sin(cycles / 20.0)), ("/check/broken", np.full(200, np.nan))]
    series += [(f"/check/flag_{name}", np.zeros(200)) for name in "abc"]
    for entity, values in series:
        stream.send_columns(
            entity,
            indexes=[
                rr.TimeColumn(CYCLE_TIMELINE, sequence=cycles),
                rr.TimeColumn(SIM_TIME_TIMELINE, duration=cycles / 1000.0),
            ],
            columns=rr.Scalars.columns(scalars=values),
        )
    stream.flush()
    stream.disconnect()
    return path


@pytest.mark.skipif(NO_BROWSER is not None, reason=str(NO_BROWSER))
@pytest.mark.timeout(600)
def test_the_series_check_fails_for_a_series_with_data_that_draws_nothing(one_broken_series: Path) -> None:
    """The per-series pixel check of the browser stage (`check_series`): of the series that all
    have data, the one that draws nothing in its view is named, the others are not; both views
    are looked at in one showing; three identical lines are told apart in one more showing
    (nested), and only the broken one is then shown alone."""
    import rerun.blueprint as rrb

    from hilrig.observe.dashboard_check import missing_series
    from hilrig.observe.reader import Trace
    from hilrig.observe.series_check import SERIES_PIXELS, check_series

    layout = rrb.Blueprint(
        rrb.TimeSeriesView(
            name="five series",
            origin="/check",
            contents=["/check/flag_a", "/check/flag_b", "/check/drawn", "/check/broken", "/check/flag_c"],
        ),
        rrb.TimeSeriesView(name="the sine again", origin="/check", contents=["/check/drawn"]),
        rrb.TimePanel(timeline=CYCLE_TIMELINE),
        collapse_panels=False,
    )
    trace = Trace.read(one_broken_series)
    assert missing_series(layout, trace) == [], "both have data: the data check cannot see it"
    out = output_dir() / "series-check"
    with served_trace(one_broken_series, "overview") as served, ViewerPage(served) as viewer:
        drawn = check_series(viewer, layout, trace, out, name="broken", trace_path=one_broken_series)
    for entity in ("/check/drawn", "/check/flag_a", "/check/flag_b", "/check/flag_c"):
        assert drawn.pixels[("five series", entity)] >= SERIES_PIXELS, drawn.pixels
    assert drawn.pixels[("the sine again", "/check/drawn")] >= SERIES_PIXELS, drawn.pixels
    assert drawn.missing() == ["broken / five series: /check/broken drew 0 pixels in its view"]
    assert [shot.name for shot in drawn.screenshots] == ["1+2.png", "1-nested.png", "1-4.png"]


# --- Without a browser ------------------------------------------------------------------------
def _varint(value: int) -> bytes:
    out = bytearray()
    while True:
        low, value = value & 0x7F, value >> 7
        out.append(low | (0x80 if value else 0))  # protocol-literal: protobuf continuation bit
        if not value:
            return bytes(out)


def _field(number: int, value: int | bytes | str) -> bytes:
    if isinstance(value, int):
        return _varint(number << 3) + _varint(value)
    data = value.encode() if isinstance(value, str) else value
    return _varint(number << 3 | 2) + _varint(len(data)) + data


def test_the_viewer_state_is_decoded_from_the_protobuf_the_viewer_answers() -> None:
    """A GetViewerStateResponse spelled by hand, field numbers as in rerun 0.41's proto."""
    active = "Recording:hilrig:run-1"
    timeline = _field(1, _field(1, "cycle")) + _field(3, _field(1, 0) + _field(2, 59_999))
    other = _field(1, "Recording:hilrig:other") + _field(
        2, _field(1, _field(1, "cycle")) + _field(3, _field(2, 7))
    )
    view = _field(2, "TimeSeries") + _field(3, "sensors") + _field(4, "/fields/sensors") + _field(5, 1)
    view += _field(6, _field(1, "error") + _field(2, "no data"))
    data = (
        _field(2, active)
        + _field(3, other)
        + _field(3, _field(1, active) + _field(2, timeline))
        + _field(5, view)
        + _field(6, RERUN_VERSION)
        + _field(7, _field(1, "trace.rrd"))
    )
    state = ViewerState.decode(data)
    assert (state.active_recording, state.recording_id) == (active, "run-1")
    assert state.timeline_ends == {"cycle": 59_999}  # of the active recording only
    assert state.shown_views() == {("sensors", "/fields/sensors")}
    assert state.view_errors() == [("sensors", ("error", "no data"))]
    assert (state.loading, state.version) == (("trace.rrd",), RERUN_VERSION)
    assert ViewerState.decode(b"").recording_id is None


@pytest.mark.parametrize(
    ("line", "fatal"),
    [
        (ConsoleLine("log", "ERROR re_viewer: a view failed", ""), True),
        (ConsoleLine("error", "thread 'main' panicked at ...", ""), True),
        (ConsoleLine("error", "Failed to load resource: 404", "http://127.0.0.1:9090/app.wasm"), True),
        (ConsoleLine("error", "Failed to load resource: net::ERR", "https://fonts.example/x.woff2"), False),
        (ConsoleLine("error", "TypeError: Failed to fetch", ""), False),
        (ConsoleLine("warning", "WebGPU is not available", ""), False),
        (ConsoleLine("error", "Uncaught RangeError", ""), True),
    ],
)
def test_only_the_viewers_own_failures_are_fatal_not_an_offline_machine(
    line: ConsoleLine, fatal: bool
) -> None:
    assert is_fatal(line) is fatal


def test_plotted_pixels_count_colour_among_the_views_not_in_the_panels() -> None:
    image = Image.new("RGB", (VIEWPORT["width"], VIEWPORT["height"]), (250, 250, 250))
    left, top, right, bottom = BLUEPRINT_AREA
    image.paste((220, 40, 40), (0, top, left, bottom))  # a selected row in the blueprint tree
    image.paste((40, 90, 220), (left, bottom, right, VIEWPORT["height"]))  # the time panel
    image.paste((128, 128, 128), (left, top, right, top + 100))  # grey: UI, not a plot
    image.paste((24, 106, 221), (left, top + 100, left + 60, top + 115))  # a text log's timeline column
    assert plotted_pixels(image) == 0
    image.paste((40, 160, 60), (left + 10, top + 200, left + 410, top + 203))  # a series line
    assert plotted_pixels(image) == 400 * 3


def test_a_series_colour_counts_inside_the_views_rectangle_only() -> None:
    from hilrig.observe.series_check import COLOUR_TOLERANCE, SERIES_PALETTE, colour_pixels

    red, green = SERIES_PALETTE[0], SERIES_PALETTE[1]
    image = Image.new("RGB", (VIEWPORT["width"], VIEWPORT["height"]), (30, 30, 30))
    left, top, _, _ = BLUEPRINT_AREA
    image.paste(red, (0, 0, left, top))  # outside the view: not its pixels
    image.paste(red, (left + 10, top + 50, left + 110, top + 54))  # its line, 100 x 4
    near = tuple(c - COLOUR_TOLERANCE if c else c for c in red)
    image.paste(near, (left + 10, top + 60, left + 20, top + 61))  # anti-aliased, still it: 10
    assert colour_pixels(image, BLUEPRINT_AREA, red) == 400 + 10
    assert colour_pixels(image, BLUEPRINT_AREA, green) == 0


def test_the_series_of_a_view_are_the_ones_it_names_or_those_under_its_origin_with_data() -> None:
    import rerun.blueprint as rrb

    from hilrig.observe.reader import Trace
    from hilrig.observe.series_check import series_of

    trace = Trace()
    trace.scalars["/bus/tpdo_delay/TPDO2"] = [0.3]
    trace.scalars["/bus/tpdo_delay/TPDO1"] = [0.2]
    trace.scalars["/bus/tpdo_delay/TPDO9"] = []  # named, never logged: nothing to draw
    trace.scalars["/bus/load"] = [50.0]
    subtree = rrb.TimeSeriesView(name="delays", origin="/bus/tpdo_delay")
    assert series_of(subtree, trace) == ["/bus/tpdo_delay/TPDO1", "/bus/tpdo_delay/TPDO2"]
    named = rrb.TimeSeriesView(name="load", origin="/", contents=["/bus/load", "+ /events/**"])
    assert series_of(named, trace) == ["/bus/load"]


def test_the_renderer_is_llvmpipe_where_mesa_is_else_swiftshader_or_as_told(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.delenv(RENDERER_VARIABLE, raising=False)
    monkeypatch.setattr(browser, "MESA_EGL", tmp_path / "50_mesa.json")
    assert renderer() == "swiftshader"
    assert chromium_flags()[-2:] == ["--use-angle=swiftshader", "--enable-unsafe-swiftshader"]
    (tmp_path / "50_mesa.json").write_text("{}")
    assert renderer() == "llvmpipe"
    assert "--use-angle=gl-egl" in chromium_flags()
    monkeypatch.setenv(RENDERER_VARIABLE, "swiftshader")
    assert renderer() == "swiftshader"
    monkeypatch.setenv(RENDERER_VARIABLE, "gpu")
    expected = "HIL_VIEWER_RENDERER=gpu: expected one of llvmpipe, swiftshader"
    with pytest.raises(BrowserUnavailableError, match=expected):
        renderer()
