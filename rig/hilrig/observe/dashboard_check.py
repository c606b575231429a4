"""Which views of a dashboard would show nothing on a given trace: every series a view names
must have data in the recording (`hilrig view TRACE --check`, and the dashboard tests); and
which dashboards a trace is checked and opened with, for the board it records.

    gaps = missing_series(blueprint("tuning"), Trace.read(Path("out/demo/trace.rrd")))
    # ["tuning / spring constant ...: /fields/modules/spring_constant_estimate has no data"]
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping

import rerun.blueprint as rrb

from hilrig.observe.blueprints import joint_dashboards, load_blueprint, robot_blueprint
from hilrig.observe.layout import ORIGIN_SUBTREE
from hilrig.observe.paths import DIFF_BASE_ROOT, DIFF_CAND_ROOT, GENERATED_DASHBOARD, absent_on_the_ideal_bus
from hilrig.observe.reader import Trace, TraceBoard
from hilrig.table import RigTable


def views(blueprint: rrb.Blueprint) -> Iterator[rrb.View]:
    """Every view of the blueprint, depth first."""

    def walk(part: rrb.Container | rrb.View) -> Iterator[rrb.View]:
        if isinstance(part, rrb.View):
            yield part
        else:
            for child in part.contents:
                yield from walk(child)

    if blueprint.root_container is not None:
        yield from walk(blueprint.root_container)


def _under(prefix: str, entities: set[str]) -> bool:
    root = prefix.rstrip("/")
    if not root:  # "/": the whole recording
        return bool(entities)
    return any(entity == root or entity.startswith(root + "/") for entity in entities)


def missing_series(blueprint: rrb.Blueprint, trace: Trace, *, name: str = "") -> list[str]:
    """One line per series a view names that has no row in the trace, and one per view whose
    queries (its origin's subtree, "+ /events/**"...) match nothing with data. The timed bus's
    series count only in a trace of a run on it (`TIMED_BUS_SERIES`)."""
    with_data = {entity for entity, rows in trace.rows.items() if rows}
    gaps: list[str] = []
    for view in views(blueprint):
        what = f"{name} / {view.name}" if name else str(view.name)
        contents = view.contents if isinstance(view.contents, list) else [str(view.contents)]
        subtrees: list[str] = []
        for content in contents:
            if content == ORIGIN_SUBTREE:
                subtrees.append(str(view.origin))
            elif content.startswith("+ "):  # a query: "+ /events/emcy/**"
                subtrees.append(content[2:].removesuffix("/**"))
            elif content not in with_data and not absent_on_the_ideal_bus(content, with_data):
                gaps.append(f"{what}: {content} has no data")
        if subtrees and not any(_under(subtree, with_data) for subtree in subtrees):
            gaps.append(f"{what}: nothing under {' or '.join(subtrees)}")
    return gaps


def unshown_series(blueprint: rrb.Blueprint, trace: Trace) -> list[str]:
    """The entities with data in the trace that no view of the blueprint shows (by name, or under
    its origin or a query): what a dashboard that draws every series leaves out."""
    named: set[str] = set()
    subtrees: list[str] = []
    for view in views(blueprint):
        contents = view.contents if isinstance(view.contents, list) else [str(view.contents)]
        for content in contents:
            if content == ORIGIN_SUBTREE:
                subtrees.append(str(view.origin))
            elif content.startswith("+ "):
                subtrees.append(content[2:].removesuffix("/**"))
            else:
                named.add(content)
    return sorted(
        entity
        for entity, rows in trace.rows.items()
        if rows and entity not in named and not any(_under(subtree, {entity}) for subtree in subtrees)
    )


def robot_node_ids(trace: Trace) -> tuple[int, ...]:
    """The modules of a robot's trace (entities under /modules/<id>), () for one board's."""
    ids = {int(parts[2]) for entity in trace.rows if (parts := entity.split("/"))[1:2] == ["modules"]}
    return tuple(sorted(ids))


def is_comparison(trace: Trace) -> bool:
    """A recording `hilrig diff` wrote (both runs under /base and /cand)."""
    return any(entity.startswith((DIFF_BASE_ROOT + "/", DIFF_CAND_ROOT + "/")) for entity in trace.rows)


def trace_table(board: TraceBoard | None, table: RigTable | None = None) -> RigTable:
    """The table of a trace's board: the one its tracer recorded (`board`), else `table`, else
    the default board's."""
    if board is not None:
        return board.table()
    return table if table is not None else RigTable.load()


def own_dashboard(board: TraceBoard | None, table: RigTable) -> str:
    """The dashboard a trace of one board opens with: the one its tracer recorded (`board`),
    else the demo joint's overview for the joint's table, else the generated one."""
    if board is not None and board.dashboard is not None:
        return board.dashboard
    return "overview" if table.is_default_board else GENERATED_DASHBOARD


def trace_blueprint(name: str, trace: Trace, table: RigTable) -> rrb.Blueprint:
    """The dashboard `name` built for `trace` of `table`'s board: the generated one with the
    trace's truth and every series it has data for, a robot's for its modules."""
    if name == GENERATED_DASHBOARD:
        present = [entity for entity, rows in trace.rows.items() if rows]
        return load_blueprint(name, table, present=present)
    node_ids = robot_node_ids(trace)
    if name == "robot" and node_ids:
        return robot_blueprint(table, node_ids)
    return load_blueprint(name, table)


def fitting_dashboards(trace: Trace, table: RigTable | None = None) -> dict[str, rrb.Blueprint]:
    """The dashboards made for this kind of trace, by name: `diff` for a comparison, `robot` (for
    the trace's own modules) for a robot's; for one board's, the demo joint's five for the joint,
    else its own (`own_dashboard`: the head's, or the one generated from its table). `table`:
    the board's when the trace records none (`trace_table`)."""
    table = trace_table(trace.board, table)
    if is_comparison(trace):
        return {"diff": load_blueprint("diff", table)}
    if robot_node_ids(trace):
        return {"robot": trace_blueprint("robot", trace, table)}
    own = own_dashboard(trace.board, table)
    names = joint_dashboards() if own in joint_dashboards() else (own,)
    return {name: trace_blueprint(name, trace, table) for name in names}


def trace_gaps(trace: Trace, dashboards: Mapping[str, rrb.Blueprint] | None = None) -> list[str]:
    """`missing_series` of every dashboard given (default: every one made for the trace)."""
    if dashboards is None:
        dashboards = fitting_dashboards(trace)
    return [gap for name, layout in dashboards.items() for gap in missing_series(layout, trace, name=name)]


__all__ = [
    "fitting_dashboards",
    "is_comparison",
    "missing_series",
    "own_dashboard",
    "robot_node_ids",
    "trace_blueprint",
    "trace_gaps",
    "trace_table",
    "unshown_series",
    "views",
]
