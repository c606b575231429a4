"""The dashboards as the rig loads them: a blueprint of dashboards/ by name (the names checked,
the table given), the generated one of any board, a robot's, the fields they plot, a blueprint
saved as a .rbl file. The one way the rig reaches dashboards/ (which imports only
`hilrig.observe.paths` and `hilrig.observe.layout` back): nothing else of hilrig imports it."""

from __future__ import annotations

import importlib.util
import sys
from collections.abc import Iterable, Sequence
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING

from hilrig import resources
from hilrig.errors import unknown_name
from hilrig.observe.paths import GENERATED_DASHBOARD
from hilrig.observe.sinks import APPLICATION_ID
from hilrig.table import RigTable

if TYPE_CHECKING:
    import rerun.blueprint as rrb


def dashboards() -> ModuleType:
    """The `dashboards` package: in the wheel hilrig.dashboards (tools/dist.py points this import
    there), in the checkout's venv the editable install's mapping of dashboards/; in a checkout run
    from PYTHONPATH alone, loaded from the checkout's dashboards/."""
    try:
        import dashboards  # type: ignore[import-not-found]

        return dashboards
    except ImportError:
        if resources.CHECKOUT is None:
            raise ImportError("hilrig's dashboards package is not installed: reinstall hilrig") from None
    root = resources.CHECKOUT / "dashboards"
    spec = importlib.util.spec_from_file_location(
        "dashboards", root / "__init__.py", submodule_search_locations=[str(root)]
    )
    if spec is None or spec.loader is None:
        raise ImportError(f"no dashboards package at {root}")
    module = importlib.util.module_from_spec(spec)
    sys.modules["dashboards"] = module
    spec.loader.exec_module(module)
    return module


def load_blueprint(
    name: str,
    table: RigTable | None = None,
    *,
    truth: Iterable[str] = (),
    present: Iterable[str] | None = None,
) -> rrb.Blueprint:
    """The dashboards/ blueprint called `name` (FieldNameError with close matches otherwise), for
    `table` (default: the board's). The generated one (GENERATED_DASHBOARD) also takes the
    plant's truth quantities and the entity paths a trace has data at (None: before a run;
    `dashboards.board`)."""
    known = dashboards().BLUEPRINTS
    if name not in known:
        raise unknown_name("dashboard", name, known)
    table = table if table is not None else RigTable.load()
    if name == GENERATED_DASHBOARD:
        generated: rrb.Blueprint = dashboards().board(table, truth, present)
        return generated
    return dashboards().blueprint(name, table)


def robot_blueprint(table: RigTable, node_ids: Sequence[int]) -> rrb.Blueprint:
    """A robot's dashboard for these modules (`dashboards.robot`)."""
    blueprint: rrb.Blueprint = dashboards().robot(table, node_ids)
    return blueprint


def joint_dashboards() -> tuple[str, ...]:
    """The demo joint's dashboards of one board's trace (`dashboards.JOINT_DASHBOARDS`)."""
    return tuple(dashboards().JOINT_DASHBOARDS)


def dashboard_fields(table: RigTable) -> list[str]:
    """Every board field a dashboard plots by name (`dashboards.joint.named_fields`)."""
    names: list[str] = dashboards().named_fields(table)
    return names


def blueprint_names() -> tuple[str, ...]:
    return tuple(dashboards().BLUEPRINTS)


def save_blueprint(blueprint: str | rrb.Blueprint, path: str | Path) -> Path:
    """Write the blueprint (one built, or the one named, for the default table) as a `.rbl`
    file for the hilrig application id."""
    path = Path(path)
    built = load_blueprint(blueprint) if isinstance(blueprint, str) else blueprint
    built.save(APPLICATION_ID, path)
    return path
