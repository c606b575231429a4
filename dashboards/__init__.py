"""Rerun blueprints (layouts) for the rig's traces, one per use; see joint.py. The demo joint's
(and a robot's, and a comparison's) in joint.py; another board's beside it (head.py, the robot
head module's), built for that board's table."""

from collections.abc import Callable

import rerun.blueprint as rrb

from dashboards.head import head
from dashboards.joint import BLUEPRINTS as JOINT_BLUEPRINTS
from dashboards.joint import named_fields
from hilrig.observe.paths import EntryTable

OTHER_BOARD_BLUEPRINTS = ("head",)
"""Dashboards of another board than the joint (its table under protocol/boards/)."""

BLUEPRINTS: dict[str, Callable[[EntryTable], rrb.Blueprint]] = {**JOINT_BLUEPRINTS, "head": head}
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


__all__ = ["BLUEPRINTS", "OTHER_BOARD_BLUEPRINTS", "blueprint", "named_fields"]
