"""The rig's timing modes: the one vocabulary every layer uses (its string values appear only at
the command line and in files; the firmware's own --mode words are `hilrig.session.firmware`'s).
A module of its own, with no imports, so the run description and the command line can name the
modes without loading the engine."""

from __future__ import annotations

import enum


class TimingMode(enum.StrEnum):
    """How the rig keeps time (DESIGN.md, "Two timing modes")."""

    LOCKSTEP = "lockstep"
    """The rig produces SYNC and each SYNC is one firmware cycle: exact simulation time."""
    REALTIME = "realtime"
    """The rig keeps its own wall-clock period next to a free-running node."""


__all__ = ["TimingMode"]
