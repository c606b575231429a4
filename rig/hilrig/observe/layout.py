"""Pieces of a Rerun layout that the dashboards (dashboards/) and the checks of them here share:
how a view names "everything under its origin", a plot's x axis over the whole run. A leaf: it
imports nothing of hilrig; dashboards/ imports it and `paths`, nothing else of the rig. It
imports rerun.blueprint, so nothing on the untraced rig's path imports it."""

from __future__ import annotations

import rerun.blueprint as rrb

ORIGIN_SUBTREE = "$origin/**"
"""A view's contents when it names no series: everything under its origin."""

WHOLE_RUN = rrb.archetypes.TimeAxis(
    view_range=rrb.TimeRange(start=rrb.TimeRangeBoundary.infinite(), end=rrb.TimeRangeBoundary.infinite())
)
"""A plot's x axis over the whole recording (on the cycle timeline the viewer would otherwise
show a window of some thousand cycles around the time cursor)."""
