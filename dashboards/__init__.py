"""Rerun blueprints (layouts) for the rig's traces, one per use; see joint.py. The demo joint's
(and a robot's, and a comparison's) in joint.py; another board's beside it (head.py, the robot
head module's), built for that board's table; and the one generated for any board from its
table and plant (board.py), which a board without hand-made dashboards opens with."""

from collections.abc import Callable

import rerun.blueprint as rrb

from dashboards.board import board
from dashboards.head import head
from dashboards.joint import BLUEPRINTS as JOINT_BLUEPRINTS
from dashboards.joint import named_fields
from dashboards.robot import robot
from hilrig.observe.paths import GENERATED_DASHBOARD, EntryTable

OTHER_BOARD_BLUEPRINTS = ("head",)
"""Dashboards of another board than the joint (its table under protocol/boards/)."""

JOINT_DASHBOARDS = ("overview", "tuning", "thermal", "faults", "bus")
"""The demo joint's dashboards of one board's trace: a joint's trace is checked against each."""

BLUEPRINTS: dict[str, Callable[[EntryTable], rrb.Blueprint]] = {
    **JOINT_BLUEPRINTS,
    "head": head,
    GENERATED_DASHBOARD: board,
}
"""Blueprint builders by name, every board's; `blueprint(name, table)` is the way to get one."""


def blueprint(name: str, table: EntryTable) -> rrb.Blueprint:
    """The blueprint called `name` for `table` (a `hilrig.table.RigTable` of its board); KeyError
    listing the names for another (`hilrig.observe.blueprints.load_blueprint` lists the close
    matches)."""
    try:
        build = BLUEPRINTS[name]
    except KeyError:
        raise KeyError(f"no dashboard named {name!r}: one of {', '.join(BLUEPRINTS)}") from None
    return build(table)


__all__ = [
    "BLUEPRINTS",
    "JOINT_DASHBOARDS",
    "OTHER_BOARD_BLUEPRINTS",
    "blueprint",
    "board",
    "named_fields",
    "robot",
]
