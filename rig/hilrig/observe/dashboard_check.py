"""Which views of a dashboard would show nothing on a given trace: every series a view names
must have data in the recording (`hilrig view TRACE --check`, and the dashboard tests).

    gaps = missing_series(blueprint("tuning"), Trace.read(Path("out/demo/trace.rrd")))
    # ["tuning / spring constant ...: /fields/modules/spring_constant_estimate has no data"]
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping

import rerun.blueprint as rrb

from dashboards.joint import ORIGIN_SUBTREE
from hilrig.observe.paths import DIFF_BASE_ROOT, DIFF_CAND_ROOT
from hilrig.observe.reader import Trace


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
    queries (its origin's subtree, "+ /events/**"...) match nothing with data."""
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
            elif content not in with_data:
                gaps.append(f"{what}: {content} has no data")
        if subtrees and not any(_under(subtree, with_data) for subtree in subtrees):
            gaps.append(f"{what}: nothing under {' or '.join(subtrees)}")
    return gaps


def robot_node_ids(trace: Trace) -> tuple[int, ...]:
    """The modules of a robot's trace (entities under /modules/<id>), () for one board's."""
    ids = {int(parts[2]) for entity in trace.rows if (parts := entity.split("/"))[1:2] == ["modules"]}
    return tuple(sorted(ids))


def is_comparison(trace: Trace) -> bool:
    """A recording `hilrig diff` wrote (both runs under /base and /cand)."""
    return any(entity.startswith((DIFF_BASE_ROOT + "/", DIFF_CAND_ROOT + "/")) for entity in trace.rows)


TRACE_SPECIFIC = ("robot", "diff")
"""Dashboards made for one kind of recording only: a robot's trace, a comparison of two runs."""


def fitting_dashboards(trace: Trace) -> dict[str, rrb.Blueprint]:
    """The dashboards made for this kind of trace, by name: `diff` for a comparison, `robot` (for
    the trace's own modules) for a robot's, every other one for one board's."""
    from dashboards.joint import BLUEPRINTS
    from dashboards.robot import robot
    from hilrig.table import RigTable

    table = RigTable.load()
    if is_comparison(trace):
        return {"diff": BLUEPRINTS["diff"](table)}
    node_ids = robot_node_ids(trace)
    if node_ids:
        return {"robot": robot(table, node_ids)}
    return {name: build(table) for name, build in BLUEPRINTS.items() if name not in TRACE_SPECIFIC}


def trace_gaps(trace: Trace, dashboards: Mapping[str, rrb.Blueprint] | None = None) -> list[str]:
    """`missing_series` of every dashboard given (default: every one made for the trace)."""
    if dashboards is None:
        dashboards = fitting_dashboards(trace)
    return [gap for name, layout in dashboards.items() for gap in missing_series(layout, trace, name=name)]


__all__ = ["fitting_dashboards", "is_comparison", "missing_series", "robot_node_ids", "trace_gaps", "views"]
