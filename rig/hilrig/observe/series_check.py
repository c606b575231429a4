"""Does every series of every plot draw something in its own view? A check in the web viewer, per
view and per series, on top of `hilrig.observe.browser.check_dashboards` (which looks at the
whole page: something plotted somewhere, the views there, no error).

    with served_trace(path, "overview") as served, ViewerPage(served) as viewer:
        drawn = check_series(viewer, blueprint("tuning", table), Trace.read(path), out / "tuning")
        drawn.missing()      # ["velocity loop ...: /fields/commands/velocity_setpoint drew 0 pixels"]

How: the time series views of the dashboard are shown by themselves, a few at a time
(`MAX_VIEWS_SHOWN`, stacked, each series of a showing given its own colour of `SERIES_PALETTE`
and a wide line by a blueprint override, legends hidden, the side panels collapsed), on a page
of `SHOWING_VIEWPORT`, so that they fill its views' area (`SHOWING_AREA`); a series is drawn
when pixels of its colour are inside that rectangle.
Its colour is its own in the showing and a view draws only inside itself, so its pixels are
its view's. Lines on top of each other hide the ones below (a setpoint its measurement follows
exactly, flags that are all 0). The hidden ones of a view are then shown together once more,
nested: the first widest, each next narrower (`nested_widths`), so each shows a band of its
colour around the ones on top of it; only a series still not found is shown alone (a view of
its own), and only then is it missing. Text logs and 3D views name no series:
`check_dashboards` covers them. Each showing costs the software-rendered viewer frames to settle,
which is why views share them, and why the page is smaller than the dashboards' own (the
viewer paints in software; a screenshot is a frame painted).

The series of a view are the entity paths it names, or (a view of everything under its origin)
the entities under its origin with scalar data in the trace.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from hilrig.observe.browser import BLUEPRINT_AREA, SETTLE_POLL_S, VIEWPORT, ViewerPage, last_cycle
from hilrig.observe.dashboard_check import views
from hilrig.observe.layout import ORIGIN_SUBTREE, WHOLE_RUN
from hilrig.observe.paths import CYCLE_TIMELINE, absent_on_the_ideal_bus

if TYPE_CHECKING:
    import rerun.blueprint as rrb
    from PIL.Image import Image
    from playwright.sync_api import ViewportSize

    from hilrig.observe.reader import Trace

SERIES_PALETTE: tuple[tuple[int, int, int], ...] = (
    (255, 0, 0), (0, 200, 0), (255, 0, 255), (255, 160, 0), (0, 230, 230), (255, 255, 0),
    (128, 0, 255), (255, 96, 160), (0, 128, 0), (160, 80, 0), (255, 220, 140), (0, 255, 140),
    (200, 0, 80), (120, 255, 0), (180, 140, 255), (255, 120, 80),
)
"""One colour per series of a view shown (a view of more series is shown 16 at a time; an 8-module
robot's angles are 16): clear colours apart from each other by 40 or more in some channel, none
near the viewer's own accent blue (`hilrig.observe.browser.UI_ACCENT_HUE`) or its greys."""
LINE_WIDTH = 4.0
"""Points: the middle of a line this wide is its own colour exactly, whatever the anti-aliasing."""
NESTED_STEP = 4.0
"""Points between the widths of series shown nested (`nested_widths`): two pixels of a band each
side, one of them clear of the anti-aliased edges."""
COLOUR_TOLERANCE = 10
"""Per channel, how far a pixel may be from a series' colour and still be it."""
SERIES_PIXELS = 20
"""Pixels of its colour a drawn series has at least (a flat line across a view has thousands)."""
MAX_VIEWS_SHOWN = 4
"""Views stacked in one showing at most: each keeps a quarter of the blueprint area's height,
room for the nested bands of a few identical lines."""
SHOWING_VIEWPORT: ViewportSize = {"width": 800, "height": 700}
"""The page while views are shown for their series: a third of VIEWPORT's pixels, so a third of
the software painting a frame costs, and room enough for MAX_VIEWS_SHOWN views' nested bands."""
SHOWING_AREA = (
    0,
    BLUEPRINT_AREA[1],
    SHOWING_VIEWPORT["width"],
    SHOWING_VIEWPORT["height"] - (VIEWPORT["height"] - BLUEPRINT_AREA[3]),
)
"""(left, top, right, bottom): where a showing's views are, the whole width (its side panels are
collapsed) between the top bar and the time panel, which keep their pixel sizes."""
STILL_S = 30.0
"""How long a view is given to hold still before its screenshot counts as it is."""


def series_of(view: rrb.View, trace: Trace) -> list[str]:
    """The entity paths `view` plots: the ones it names (but a timed bus's on a trace of the ideal
    bus, which has none), or those under its origin with scalars."""
    contents = view.contents if isinstance(view.contents, list) else [str(view.contents)]
    with_data = {entity for entity, values in trace.scalars.items() if values}
    named = [str(c) for c in contents if str(c) != ORIGIN_SUBTREE and not str(c).startswith("+ ")]
    named = [series for series in named if not absent_on_the_ideal_bus(series, with_data)]
    if ORIGIN_SUBTREE in (str(c) for c in contents):
        root = str(view.origin).rstrip("/")
        named += sorted(e for e, values in trace.scalars.items() if values and e.startswith(root + "/"))
    return named


def colour_pixels(image: Image, box: tuple[int, int, int, int], rgb: tuple[int, int, int]) -> int:
    """Pixels inside `box` within COLOUR_TOLERANCE of `rgb` in every channel."""
    import numpy as np

    pixels = np.asarray(image.convert("RGB").crop(box), dtype=np.int16)
    near = np.abs(pixels - np.asarray(rgb, dtype=np.int16)).max(axis=2) <= COLOUR_TOLERANCE
    return int(np.count_nonzero(near))


def nested_widths(count: int) -> list[float]:
    """Line widths for `count` series that may lie on top of each other: the first widest, each
    next NESTED_STEP narrower, down to LINE_WIDTH. Drawn in order (the later on top), identical
    lines then show as nested bands, each of its own colour."""
    return [LINE_WIDTH + NESTED_STEP * (count - 1 - k) for k in range(count)]


@dataclass(frozen=True)
class Plot:
    """A view as one showing plots it: `series` (some or all of the view's), named `name` there,
    each line `widths` wide (default LINE_WIDTH); `label` names its part of the screenshot's file."""

    view: rrb.TimeSeriesView
    series: tuple[str, ...]
    name: str
    label: str
    widths: tuple[float, ...] | None = None


def together(plots: Sequence[Plot], time_panel: rrb.TimePanel | None) -> rrb.Blueprint:
    """A blueprint of `plots` stacked top to bottom, nothing else in it; the series of all of
    them take SERIES_PALETTE's colours in order, so that no two share one."""
    import rerun as rr
    import rerun.blueprint as rrb

    colours = iter(SERIES_PALETTE)
    shown = []
    for plot in plots:
        widths = plot.widths if plot.widths is not None else (LINE_WIDTH,) * len(plot.series)
        overrides = {
            path: rr.SeriesLines.from_fields(colors=[next(colours)], widths=[width])
            for path, width in zip(plot.series, widths, strict=True)
        }
        shown.append(
            rrb.TimeSeriesView(
                name=plot.name,
                origin=plot.view.origin,
                contents=list(plot.series),
                axis_x=WHOLE_RUN,
                plot_legend=rrb.PlotLegend(visible=False),
                overrides=overrides,
            )
        )
    top: rrb.Container | rrb.View = shown[0] if len(shown) == 1 else rrb.Vertical(*shown)
    parts: list[rrb.Container | rrb.View | rrb.TimePanel | rrb.BlueprintPanel | rrb.SelectionPanel] = [
        top,
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
    ]
    if time_panel is not None:
        parts.append(time_panel)
    return rrb.Blueprint(*parts, collapse_panels=False)  # type: ignore[arg-type]


def alone(
    view: rrb.TimeSeriesView,
    series: Sequence[str],
    time_panel: rrb.TimePanel | None,
    *,
    name: str | None = None,
    widths: Sequence[float] | None = None,
) -> rrb.Blueprint:
    """A blueprint of `view` alone (called `name`, default its own), plotting `series`, each in its
    SERIES_PALETTE colour, LINE_WIDTH wide (or `widths`), no legend."""
    shown = name if name is not None else str(view.name)
    return together([Plot(view, tuple(series), shown, shown, tuple(widths) if widths else None)], time_panel)


@dataclass
class SeriesDrawn:
    """Per (view, series) of one dashboard, the pixels of its colour in its view."""

    dashboard: str
    pixels: dict[tuple[str, str], int] = field(default_factory=dict)
    screenshots: list[Path] = field(default_factory=list)

    def missing(self) -> list[str]:
        return [
            f"{self.dashboard} / {view}: {series} drew {count} pixels in its view"
            for (view, series), count in self.pixels.items()
            if count < SERIES_PIXELS
        ]


def _still_screenshot(viewer: ViewerPage, path: Path) -> Image:
    """Screenshots until two in a row are the same inside the views (or STILL_S passed)."""
    deadline = time.monotonic() + STILL_S
    previous: bytes | None = None
    while True:
        image = viewer.screenshot(path)
        pixels = image.crop(SHOWING_AREA).tobytes()
        if pixels == previous or time.monotonic() > deadline:
            return image
        previous = pixels
        time.sleep(SETTLE_POLL_S)


def _time_series_views(blueprint: rrb.Blueprint) -> Iterator[rrb.TimeSeriesView]:
    import rerun.blueprint as rrb

    for view in views(blueprint):
        if isinstance(view, rrb.TimeSeriesView):
            yield view


_showings = itertools.count(1)
"""Numbers the showings of this process: each one's views are named apart from any shown before,
so that the wait for a showing knows it by its names."""


def _groups(plots: Sequence[Plot]) -> Iterator[list[Plot]]:
    """`plots` in order, as few to a showing as MAX_VIEWS_SHOWN and the palette allow."""
    group: list[Plot] = []
    for plot in plots:
        if group and (
            len(group) == MAX_VIEWS_SHOWN
            or sum(len(p.series) for p in group) + len(plot.series) > len(SERIES_PALETTE)
        ):
            yield group
            group = []
        group.append(plot)
    if group:
        yield group


def _show(
    viewer: ViewerPage,
    plots: Sequence[Plot],
    time_panel: rrb.TimePanel | None,
    whole: dict[str, int] | None,
    path: Path,
    drawn: SeriesDrawn,
) -> list[dict[str, int]]:
    """Show `plots` together, screenshot them to `path` once still: per plot, each series'
    pixels of its colour."""
    number = next(_showings)
    named = [
        Plot(plot.view, plot.series, f"{plot.name} · {number}", plot.label, plot.widths) for plot in plots
    ]
    viewer.show_dashboard(together(named, time_panel), whole)
    image = _still_screenshot(viewer, path)
    drawn.screenshots.append(path)
    colours = iter(SERIES_PALETTE)
    return [
        {entity: colour_pixels(image, SHOWING_AREA, next(colours)) for entity in plot.series}
        for plot in plots
    ]


def check_series(
    viewer: ViewerPage,
    blueprint: rrb.Blueprint,
    trace: Trace,
    out_dir: Path,
    *,
    name: str,
    trace_path: Path,
    checked: dict[tuple[str, tuple[str, ...]], dict[str, int]] | None = None,
) -> SeriesDrawn:
    """Show the time series views of `blueprint` by themselves in `viewer` (a page of a served
    trace), a few at a time, and count each series' pixels (see the module); screenshots to
    out_dir/<view numbers>.png (`1+2+3.png`; `-nested` for hidden series shown again nested,
    `<view>-<series>` for a series looked at alone). `checked`: views (origin, series) already
    looked at with what they drew, e.g. by another dashboard of the same trace (the overview's
    control mode plot is the faults' too): taken from there, and filled with this dashboard's.
    Leaves the page at SHOWING_VIEWPORT (`check_dashboards` sets its own size again)."""
    checked = {} if checked is None else checked
    end = last_cycle(trace_path)
    whole = {CYCLE_TIMELINE: end} if end is not None else None
    time_panel = blueprint.time_panel
    out_dir.mkdir(parents=True, exist_ok=True)
    viewer.resize(SHOWING_VIEWPORT)
    drawn = SeriesDrawn(name)
    keys: list[tuple[rrb.TimeSeriesView, tuple[str, tuple[str, ...]]]] = []
    plots: list[Plot] = []
    numbers: list[tuple[int, int]] = []  # per plot: its view's number, its first series' index
    for number, view in enumerate(_time_series_views(blueprint), start=1):
        every = series_of(view, trace)
        key = (str(view.origin), tuple(every))
        looked_at = key in checked or any(key == earlier for _, earlier in keys)  # a view twice
        keys.append((view, key))
        if looked_at:
            continue
        for first in range(0, len(every), len(SERIES_PALETTE)):  # as many colours at a time
            label = str(number) if not first else f"{number}-from-{first + 1}"
            plots.append(Plot(view, tuple(every[first : first + len(SERIES_PALETTE)]), str(view.name), label))
            numbers.append((number, first))
    counts: dict[tuple[str, str], int] = {}  # (view name, series) -> pixels
    for group in _groups(plots):
        stem = "+".join(plot.label for plot in group)
        seen = _show(viewer, group, time_panel, whole, out_dir / f"{stem}.png", drawn)
        for plot, pixels in zip(group, seen, strict=True):
            counts.update({(plot.name, entity): n for entity, n in pixels.items()})
        # Hidden under the others, or not drawn: the hidden ones of each view shown again
        # together, nested (lines on top of each other then each show a band).
        hidden = [
            Plot(plot.view, tuple(e for e in plot.series if counts[(plot.name, e)] < SERIES_PIXELS),
                 plot.name, plot.label)
            for plot in group
        ]
        nested = [
            Plot(p.view, p.series, p.name, p.label, tuple(nested_widths(len(p.series))))
            for p in hidden
            if len(p.series) > 1
        ]
        if nested:
            stem = "+".join(plot.label for plot in nested)
            seen = _show(viewer, nested, time_panel, whole, out_dir / f"{stem}-nested.png", drawn)
            for plot, pixels in zip(nested, seen, strict=True):
                counts.update({(plot.name, entity): n for entity, n in pixels.items()})
    # Any series still not found: each alone in a view of its own, a few views to a showing.
    single = [
        Plot(plot.view, (entity,), f"{plot.name}: {entity}", f"{number}-{first + k + 1}")
        for plot, (number, first) in zip(plots, numbers, strict=True)
        for k, entity in enumerate(plot.series)
        if counts[(plot.name, entity)] < SERIES_PIXELS
    ]
    for group in _groups(single):
        stem = "+".join(plot.label for plot in group)
        seen = _show(viewer, group, time_panel, whole, out_dir / f"{stem}.png", drawn)
        for plot, pixels in zip(group, seen, strict=True):
            ((entity, n),) = pixels.items()
            counts[(str(plot.view.name), entity)] = n
    for view, key in keys:
        if key not in checked:
            checked[key] = {entity: counts[(str(view.name), entity)] for entity in key[1]}
        drawn.pixels.update({(str(view.name), entity): n for entity, n in checked[key].items()})
    return drawn


__all__ = [
    "MAX_VIEWS_SHOWN",
    "SERIES_PALETTE",
    "SERIES_PIXELS",
    "SHOWING_AREA",
    "SHOWING_VIEWPORT",
    "SeriesDrawn",
    "alone",
    "check_series",
    "colour_pixels",
    "nested_widths",
    "series_of",
    "together",
]
