"""The NMT master's own frames on a bus that is the caller's, for a board with no rig in front
of it (`hilrig nmt`, `hilrig record --nmt-start`): NMT commands, SYNC, and what one node's
boot-up and heartbeat frames say back. canopen's NMT master and SYNC service send them; its
receive thread runs only while a heartbeat is watched::

    with BusMaster(bus) as master:
        watch = master.watch_heartbeat(0x10)
        master.nmt(NmtCommand.RESET_NODE, 0x10)
        heard = watch.wait_for(NmtState.INITIALISING, since=0, timeout_s=3.0)
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Self

import can
import canopen

from boardproto.cia301 import HEARTBEAT_STATE_MASK, SYNC_COUNTER_MAX, NmtCommand, NmtState, heartbeat_cob_id


@dataclass(frozen=True)
class Heard:
    state: int  # the heartbeat's state byte (0 = boot-up)
    at: float  # time.monotonic()


class HeartbeatWatch:
    """What one node's boot-up and heartbeat frames said, as they arrive (canopen's receive
    thread calls `on_frame`)."""

    def __init__(self) -> None:
        self.heard: list[Heard] = []
        self._changed = threading.Condition()

    def on_frame(self, can_id: int, data: bytearray, timestamp: float) -> None:
        if len(data) != 1:
            return
        with self._changed:
            self.heard.append(Heard(data[0] & HEARTBEAT_STATE_MASK, time.monotonic()))
            self._changed.notify_all()

    def wait_for(self, state: NmtState, since: int, timeout_s: float) -> Heard | None:
        """The first frame from `since` on (an index into `heard`) showing `state`, or None."""
        with self._changed:
            self._changed.wait_for(lambda: self._find(state, since) is not None, timeout_s)
            return self._find(state, since)

    def _find(self, state: NmtState, since: int) -> Heard | None:
        return next((h for h in self.heard[since:] if h.state == state), None)


class BusMaster:
    """NMT commands and SYNC on `bus` (a context manager; the bus stays the caller's). It only
    sends until `watch_heartbeat` makes it listen."""

    def __init__(self, bus: can.BusABC) -> None:
        self.network = canopen.Network(bus)  # not connected: only sends unless it has to listen

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def close(self) -> None:
        """Stop the receive thread, if `watch_heartbeat` started one."""
        if self.network.notifier is not None:
            self.network.notifier.stop(1.0)
            self.network.notifier = None

    def watch_heartbeat(self, node_id: int) -> HeartbeatWatch:
        """A watch of node `node_id`'s boot-up and heartbeat frames from now on."""
        watch = HeartbeatWatch()
        self.network.subscribe(heartbeat_cob_id(node_id), watch.on_frame)
        if self.network.notifier is None:
            self.network.connect()  # the bus is given: this starts canopen's receive thread
        return watch

    def nmt(self, command: NmtCommand, node_id: int) -> None:
        """Send an NMT command to node `node_id` (0: every node)."""
        master = canopen.nmt.NmtMaster(node_id)
        master.network = self.network
        master.send_command(int(command))

    def sync(self, counter: int) -> None:
        """Send SYNC with `counter` (1..240)."""
        if not 1 <= counter <= SYNC_COUNTER_MAX:
            raise ValueError(f"SYNC counter: expected 1..{SYNC_COUNTER_MAX}, got {counter}")
        self.network.sync.transmit(counter)


__all__ = ["BusMaster", "Heard", "HeartbeatWatch"]
