"""The Rerun blueprint of a modular robot's trace: the chain in 3D (MuJoCo's body poses) beside
every joint's commanded vs actual angle on one timeline, duties, torques and every event.

    blueprint("robot")                    # modules 1..8
    robot(table, node_ids=(1, 2, 3))      # the modules of a given robot (`hilrig sim --modules`)

Paths come from `hilrig.observe.paths` (each module's fields under /modules/<id>), names are checked
against board.toml like every other dashboard.
"""

from __future__ import annotations

from collections.abc import Sequence

import rerun.blueprint as rrb

from hilrig.observe.paths import (
    EVENTS_ROOT,
    ROBOT_ROOT,
    SIM_TIME_TIMELINE,
    EntryTable,
    entity_paths,
    module_root,
    truth_path,
)

DEFAULT_NODE_IDS = tuple(range(1, 9))
"""The modules a robot blueprint shows when not told: 1..8, `hilrig sim --modules 8`."""


def robot(table: EntryTable, node_ids: Sequence[int] = DEFAULT_NODE_IDS) -> rrb.Blueprint:
    """The chain in 3D and, per joint on one plot, the angle commanded vs measured."""
    table.check(("position_setpoint", "output_position", "motor_duty_command", "joint_torque"))
    paths = entity_paths(table)

    def each(name: str) -> list[str]:
        return [module_root(node_id) + paths[name] for node_id in node_ids]

    events = [f"+ {EVENTS_ROOT}/**", *(f"+ {module_root(node_id)}{EVENTS_ROOT}/**" for node_id in node_ids)]
    return rrb.Blueprint(
        rrb.Vertical(
            rrb.Horizontal(
                rrb.Spatial3DView(name="robot (MuJoCo body poses)", origin=ROBOT_ROOT),
                rrb.TimeSeriesView(
                    name="joint angles [rad]: commanded (position_setpoint) vs measured (output_position)",
                    origin="/",
                    contents=[*each("position_setpoint"), *each("output_position")],
                ),
                column_shares=[1, 1],
            ),
            rrb.Horizontal(
                rrb.TimeSeriesView(
                    name="motor duty [1]: commanded by each module's firmware",
                    origin="/",
                    contents=each("motor_duty_command"),
                ),
                rrb.TimeSeriesView(
                    name="joint torque [N*m]: measured vs true spring torque",
                    origin="/",
                    contents=[
                        *each("joint_torque"),
                        *(module_root(node_id) + truth_path("spring_torque_nm") for node_id in node_ids),
                    ],
                ),
            ),
            rrb.TextLogView(name="events: robot and modules", origin="/", contents=events),
            row_shares=[3, 2, 1],
        ),
        rrb.TimePanel(timeline=SIM_TIME_TIMELINE),
        collapse_panels=False,
    )
