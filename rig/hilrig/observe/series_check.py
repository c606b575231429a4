"""Does every series of every plot draw something in its own view? A check in the web viewer, per
view and per series, on top of `hilrig.observe.browser.check_dashboards` (which looks at the
whole page: something plotted somewhere, the views there, no error).

    with served_trace(path, "overview") as served, ViewerPage(served) as viewer:
        drawn = check_series(viewer, blueprint("tuning", table), Trace.read(path), out / "tuning")
        drawn.missing()      # ["velocity loop ...: /fields/commands/velocity_setpoint drew 0 pixels"]

How: each time series view of the dashboard is shown alone (it then fills the blueprint's area,
`BLUEPRINT_AREA`: that rectangle is the view's), with its legend hidden and each of its series
given its own colour of `SERIES_PALETTE` and a wide line by a blueprint override; a series is
drawn when pixels of its colour are inside that rectangle. Lines on top of each other hide the
ones below (a setpoint its measurement follows exactly, flags that are all 0). Identical lines (flags
all 0) are then shown together once more, nested: the first widest, each next narrower
(`nested_widths`), so each shows a band of its colour around the ones on top of it; only a
series still not found is shown alone, and only then is it missing. Text logs
and 3D views name no series: `check_dashboards` covers them.

The series of a view are the entity paths it names, or (a view of everything under its origin)
the entities under its origin with scalar data in the trace.
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from dashboards.joint import ORIGIN_SUBTREE, WHOLE_RUN
from hilrig.observe.browser import BLUEPRINT_AREA, SETTLE_POLL_S, ViewerPage, last_cycle
from hilrig.observe.dashboard_check import views
from hilrig.observe.paths import CYCLE_TIMELINE

if TYPE_CHECKING:
    import rerun.blueprint as rrb
    from PIL.Image import Image

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
STILL_S = 30.0
"""How long a view is given to hold still before its screenshot counts as it is."""


def series_of(view: rrb.View, trace: Trace) -> list[str]:
    """The entity paths `view` plots: the ones it names, or those under its origin with scalars."""
    contents = view.contents if isinstance(view.contents, list) else [str(view.contents)]
    named = [str(c) for c in contents if str(c) != ORIGIN_SUBTREE and not str(c).startswith("+ ")]
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
    import rerun as rr
    import rerun.blueprint as rrb

    line_widths = list(widths) if widths is not None else [LINE_WIDTH] * len(series)
    overrides = {
        path: rr.SeriesLines.from_fields(colors=[SERIES_PALETTE[k]], widths=[line_widths[k]])
        for k, path in enumerate(series)
    }
    shown = rrb.TimeSeriesView(
        name=name if name is not None else str(view.name),
        origin=view.origin,
        contents=list(series),
        axis_x=WHOLE_RUN,
        plot_legend=rrb.PlotLegend(visible=False),
        overrides=overrides,
    )
    parts: list[rrb.Container | rrb.View | rrb.TimePanel] = [shown]
    if time_panel is not None:
        parts.append(time_panel)
    return rrb.Blueprint(*parts, collapse_panels=False)  # type: ignore[arg-type]


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
        pixels = image.crop(BLUEPRINT_AREA).tobytes()
        if pixels == previous or time.monotonic() > deadline:
            return image
        previous = pixels
        time.sleep(SETTLE_POLL_S)


def _time_series_views(blueprint: rrb.Blueprint) -> Iterator[rrb.TimeSeriesView]:
    import rerun.blueprint as rrb

    for view in views(blueprint):
        if isinstance(view, rrb.TimeSeriesView):
            yield view


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
    """Show each time series view of `blueprint` alone in `viewer` (a page of a served trace) and
    count each series' pixels in it (see the module); screenshots to out_dir/<view number>.png
    (and <view number>-<series number>.png for a series looked at alone). `checked`: views
    (origin, series) already looked at with what they drew, e.g. by another dashboard of the
    same trace (the overview's control mode plot is the faults' too): taken from there, and
    filled with this dashboard's."""
    checked = {} if checked is None else checked
    end = last_cycle(trace_path)
    whole = {CYCLE_TIMELINE: end} if end is not None else None
    out_dir.mkdir(parents=True, exist_ok=True)
    drawn = SeriesDrawn(name)
    for number, view in enumerate(_time_series_views(blueprint), start=1):
        every = series_of(view, trace)
        key = (str(view.origin), tuple(every))
        if key in checked:
            drawn.pixels.update({(str(view.name), entity): n for entity, n in checked[key].items()})
            continue
        for first in range(0, len(every), len(SERIES_PALETTE)):  # as many colours at a time
            series = every[first : first + len(SERIES_PALETTE)]
            # Each showing named apart from the one before: the wait knows the switch by it.
            name = str(view.name) if not first else f"{view.name} (series {first + 1} on)"
            viewer.show_dashboard(alone(view, series, blueprint.time_panel, name=name), whole)
            path = out_dir / (f"{number}.png" if not first else f"{number}-from-{first + 1}.png")
            image = _still_screenshot(viewer, path)
            drawn.screenshots.append(path)
            counts = {
                entity: colour_pixels(image, BLUEPRINT_AREA, SERIES_PALETTE[k])
                for k, entity in enumerate(series)
            }
            # Hidden under the others, or not drawn: the hidden ones shown again together, nested
            # (lines on top of each other then each show a band), then any still missing alone.
            hidden = [e for e in series if counts[e] < SERIES_PIXELS]
            if len(hidden) > 1:
                nested = alone(view, hidden, blueprint.time_panel, name=f"{name} (hidden, nested)",
                               widths=nested_widths(len(hidden)))
                viewer.show_dashboard(nested, whole)
                again = out_dir / f"{number}-nested{'' if not first else f'-from-{first + 1}'}.png"
                nested_shot = _still_screenshot(viewer, again)
                drawn.screenshots.append(again)
                for k, entity in enumerate(hidden):
                    counts[entity] = colour_pixels(nested_shot, BLUEPRINT_AREA, SERIES_PALETTE[k])
            for k, entity in enumerate(series):
                if counts[entity] < SERIES_PIXELS:
                    by_itself = alone(view, [entity], blueprint.time_panel, name=f"{view.name}: {entity}")
                    viewer.show_dashboard(by_itself, whole)
                    single = out_dir / f"{number}-{first + k + 1}.png"
                    alone_shot = _still_screenshot(viewer, single)
                    counts[entity] = colour_pixels(alone_shot, BLUEPRINT_AREA, SERIES_PALETTE[0])
                    drawn.screenshots.append(single)
                drawn.pixels[(str(view.name), entity)] = counts[entity]
        checked[key] = {entity: drawn.pixels[(str(view.name), entity)] for entity in every}
    return drawn


__all__ = [
    "SERIES_PALETTE",
    "SERIES_PIXELS",
    "SeriesDrawn",
    "alone",
    "check_series",
    "colour_pixels",
    "nested_widths",
    "series_of",
]
