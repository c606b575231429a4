"""Observers of a rig: what watches its cycles and events without being woven into the driver.

The tracer (`hilrig.observe.tracer.Tracer`) is one; a scenario can add its own (`Rig.add_observer`).
Every method has a do-nothing default, so an observer implements only what it needs. Cycle
callbacks run on the rig's thread and must be cheap (hand the work to a thread of your own);
event callbacks may come from canopen's receive thread (heartbeats).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from boardproto.cia301 import NmtState
    from hilrig.engine.driver import CycleResult, History
    from hilrig.plants.interface import Plant
    from hilrig.wire.node import EmcyRecord


class RigObserver:
    """Base of everything that watches a `Rig`: override what you need."""

    def on_plant(self, plant: Plant) -> None:
        """The rig's plant (`hilrig.plants.interface.Plant`: its truth's names and columns, its
        truth parameters), once, when the observer is attached."""

    def on_history(self, history: History) -> None:
        """The rig's per-cycle history, once, when the observer is attached: an observer that
        wants columns rather than rows can take them from it (`History.mark`)."""

    def on_configured(self, *, truth: bool) -> None:
        """The rig read the node's PDO configuration (at start, and again after a restart): the
        history now has rows for every PDO it will fill, and the plant's truth when `truth`."""

    def on_polled(self, names: tuple[str, ...], every_cycles: int) -> None:
        """These fields travel in no PDO and are read over SDO every `every_cycles` cycles into
        the history (`Rig.poll_over_sdo`): sparser than the rest, and worth saying so."""

    def on_cycle(self, result: CycleResult) -> None:
        """One completed cycle (tick): what went out, what came back, the plant's truth."""

    def on_nmt(self, state: NmtState, t: float, *, cycle: int | None, source: str) -> None:
        """An NMT state change: by a command the rig sent, or seen in a heartbeat/boot-up."""

    def on_emcy(self, record: EmcyRecord) -> None:
        """An EMCY the node sent, stamped with the cycle it arrived in."""

    def on_sdo_write(self, name: str, value: float, *, cycle: int, t: float) -> None:
        """A value the rig wrote by SDO."""

    def on_sdo_abort(self, what: str, code: int, *, cycle: int, t: float) -> None:
        """An SDO transfer the node refused (`what` says which, with the code in words)."""

    def on_event(self, path: str, text: str, *, warning: bool, cycle: int, t: float) -> None:
        """Anything else worth a line on the timeline (e.g. an injected fault, under `path`)."""


__all__ = ["RigObserver"]
