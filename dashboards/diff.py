"""The Rerun blueprint of a comparison of two runs (`hilrig diff BASE.rrd CAND.rrd`): what
changed since the last good run.

    diff(table)     # the joint's controlled quantities, base vs cand; every difference; where

Top: the first divergence and each series' own, as text entries on the cycle they happened
(click one to move the time cursor there). Then per controlled quantity the base run and the
candidate on one plot, and below it their difference (cand - base), flat at 0 wherever the runs
agree; one unit per plot. Every other series' difference is in the recording under /diff, to
drag into a view. Paths come from `hilrig.observe.paths`.
"""

from __future__ import annotations

import rerun.blueprint as rrb

from hilrig.observe.paths import (
    CYCLE_TIMELINE,
    DIFF_BASE_ROOT,
    DIFF_CAND_ROOT,
    DIFF_EVENTS_PATH,
    DIFF_ROOT,
    EntryTable,
    entity_paths,
)

COMPARED_QUANTITIES: tuple[tuple[str, str], ...] = (
    ("velocity [rad/s]", "output_velocity"),
    ("torque [N*m]", "joint_torque"),
    ("position [rad]", "output_position"),
    ("motor duty [1]", "motor_duty_command"),
)
"""(title, field) of each base-vs-candidate plot: what the joint is told to control, and the
command it turned that into."""


def diff(table: EntryTable) -> rrb.Blueprint:
    """Where the two runs part, and how far."""
    table.check(name for _, name in COMPARED_QUANTITIES)
    paths = entity_paths(table)
    whole_run = rrb.archetypes.TimeAxis(
        view_range=rrb.TimeRange(start=rrb.TimeRangeBoundary.infinite(), end=rrb.TimeRangeBoundary.infinite())
    )

    def both(title: str, name: str) -> rrb.TimeSeriesView:
        return rrb.TimeSeriesView(
            name=f"{title}: {name}, base vs cand",
            origin="/",
            contents=[DIFF_BASE_ROOT + paths[name], DIFF_CAND_ROOT + paths[name]],
            axis_x=whole_run,
        )

    def apart(title: str, name: str) -> rrb.TimeSeriesView:
        return rrb.TimeSeriesView(
            name=f"{title}: {name}, cand - base",
            origin="/",
            contents=[DIFF_ROOT + paths[name]],
            axis_x=whole_run,
        )

    return rrb.Blueprint(
        rrb.Vertical(
            rrb.TextLogView(
                name="where the runs part (first divergence of each series)", origin=DIFF_EVENTS_PATH
            ),
            rrb.Horizontal(*(both(title, name) for title, name in COMPARED_QUANTITIES)),
            rrb.Horizontal(*(apart(title, name) for title, name in COMPARED_QUANTITIES)),
            row_shares=[2, 3, 2],
        ),
        rrb.TimePanel(timeline=CYCLE_TIMELINE),
        collapse_panels=False,
    )
