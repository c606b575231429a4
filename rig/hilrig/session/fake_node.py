"""An in-process stand-in for the firmware, to test the rig without a firmware process.

A canopen `LocalNode` built from the same EDS answers SDO (with range checks from board.toml),
follows NMT, and answers each SYNC with the TPDOs due at it, packed by canopen's own PDO maps.
What it sends is computed by a `law` from the RPDO values it received, so tests can predict
every frame::

    fake = FakeJointNode(can.Bus(interface="virtual", channel="t"), table=RigTable.load())
    fake.boot()
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import can
import canopen
from canopen.pdo import PdoVariable
from canopen.sdo import SdoAbortedError

from boardproto import Field
from boardproto.cia301 import SYNC_COB_ID, NmtCommand, NmtState, SdoAbortCode, due_at_sync, heartbeat_cob_id
from hilrig.engine.driver import ProcessActivity, thread_activity
from hilrig.table import LedPattern, RigTable
from hilrig.wire.node import RECEIVE_POLL_S

Value = float | int
Law = Callable[[Mapping[str, Value]], Mapping[str, Value]]
"""Inputs (every RPDO-mapped object's last value) -> outputs by name (others: table default)."""

_STATE_BY_NAME = {
    "INITIALISING": NmtState.INITIALISING,
    "STOPPED": NmtState.STOPPED,
    "OPERATIONAL": NmtState.OPERATIONAL,
    "PRE-OPERATIONAL": NmtState.PRE_OPERATIONAL,
}

DUTY_PER_VELOCITY_SETPOINT = 200
"""Default law: motor_duty = velocity_setpoint * 200 (I16, clamped to +-10000)."""


def default_law(inputs: Mapping[str, Value]) -> dict[str, Value]:
    """A predictable controller: duty proportional to the velocity setpoint, LED on,
    motor_velocity/output_velocity echo the two encoder counters."""
    duty = round(float(inputs["velocity_setpoint"]) * DUTY_PER_VELOCITY_SETPOINT)
    return {
        "motor_duty": max(-10000, min(10000, duty)),
        "led_pattern": int(LedPattern.ON),
        "motor_velocity": float(inputs["motor_encoder_counts"]),
        "output_velocity": float(inputs["output_encoder_counts"]),
    }


class FakeJointNode:
    """LocalNode on its own bus handle; answers SYNC like the firmware in lockstep mode."""

    def __init__(
        self,
        bus: can.BusABC,
        *,
        table: RigTable,
        node_id: int | None = None,
        eds: str | Path | None = None,
        law: Law = default_law,
    ) -> None:
        from hilrig.engine.rig import DEFAULT_EDS_PATH  # late: rig imports the world

        self.table = table
        self.node_id = node_id if node_id is not None else table.board.node.default_node_id
        self.law = law
        self.network = canopen.Network(bus)
        self.local = canopen.LocalNode(self.node_id, str(eds or DEFAULT_EDS_PATH))
        self.network.add_node(self.local)
        self.local.rpdo.read(from_od=True)
        self.local.tpdo.read(from_od=True)
        self.syncs: list[int] = []
        """SYNC counter byte of every SYNC received while operational."""
        self.drop: Callable[[int, int], bool] = lambda sync_number, tpdo_number: False
        """Return True to leave TPDO `tpdo_number` out at SYNC `sync_number` (fault injection)."""
        self.last_inputs: dict[str, Value] = {}
        self._sync_number = 0
        self._receive_thread: int | None = None
        """Native id of the thread that runs the node's callbacks, once one ran (`activity`)."""
        self._lock = threading.Lock()
        self._inputs: dict[str, PdoVariable] = {
            var.name: var for m in self.local.rpdo.map.values() if m.enabled for var in m.map
        }
        self.local.add_write_callback(self._check_range)
        self.network.subscribe(0, self._after_nmt)  # after NmtSlave, which subscribed first
        self.network.subscribe(SYNC_COB_ID, self._on_sync)
        self.network.NOTIFIER_CYCLE = RECEIVE_POLL_S
        self.network.connect()  # bus given: only starts the receive thread

    def close(self) -> None:
        self.local.nmt.stop_heartbeat()
        if self.network.notifier is not None:
            self.network.notifier.stop(self.network.NOTIFIER_SHUTDOWN_TIMEOUT)
            self.network.notifier = None

    def activity(self) -> ProcessActivity | None:
        """What the thread that answers SYNCs is doing, for the rig's hang guard (`Rig(activity=)`):
        the fake gets the firmware's verdicts, idle or spinning, and a busy host is none. None
        before the first NMT command or SYNC reached it (the guard then counts wall time)."""
        thread = self._receive_thread
        return thread_activity(thread) if thread is not None else None

    @property
    def state(self) -> NmtState:
        return _STATE_BY_NAME[self.local.nmt.state]

    def boot(self) -> None:
        """Enter pre-operational (canopen starts the heartbeat) and send the boot-up message."""
        self.local.nmt.state = "PRE-OPERATIONAL"
        self.network.send_message(heartbeat_cob_id(self.node_id), bytes([NmtState.INITIALISING]))

    def send_emcy(self, code: int, register: int, data: bytes = b"") -> None:
        self.local.emcy.send(code, register, data)

    def set_pdo_parameter(self, index: int, subindex: int, value: int) -> None:
        """Change a PDO parameter as a remap over SDO would, before the rig reads it."""
        od = self.local.object_dictionary[index][subindex]
        self.local.data_store.setdefault(index, {})[subindex] = od.encode_raw(value)

    def _after_nmt(self, can_id: int, data: bytearray, timestamp: float) -> None:
        self._receive_thread = threading.get_native_id()
        if data[0] == NmtCommand.START and data[1] in (0, self.node_id):
            with self._lock:
                self._sync_number = 0  # the firmware counts SYNCs from entering operational

    def _check_range(self, index: int, subindex: int, od: Any, data: bytes, **_: Any) -> None:
        entry = self.table.entry_at(index, subindex)
        if entry is None:
            return
        value = od.decode_raw(data)
        if value > entry.max:
            raise SdoAbortedError(SdoAbortCode.VALUE_TOO_HIGH)
        if value < entry.min:
            raise SdoAbortedError(SdoAbortCode.VALUE_TOO_LOW)

    def _on_sync(self, can_id: int, data: bytearray, timestamp: float) -> None:
        self._receive_thread = threading.get_native_id()
        if self.state is not NmtState.OPERATIONAL:
            return
        with self._lock:
            self._sync_number += 1
            sync_number = self._sync_number
            self.syncs.append(data[0] if data else 0)
        inputs = {name: var.raw for name, var in self._inputs.items()}
        self.last_inputs = inputs
        outputs = dict(self.law(inputs))
        for number, pdo_map in self.local.tpdo.map.items():
            if not pdo_map.enabled or not due_at_sync(pdo_map.trans_type or 0, sync_number):
                continue
            if self.drop(sync_number, number):
                continue
            for var in pdo_map.map:
                entry = self.table.entry(var.name)
                var.raw = outputs.get(var.name, entry.default if isinstance(entry, Field) else 0)
            pdo_map.transmit()
