"""What the lockstep and the real-time driver share: the node's PDO roles, the RPDO values the rig
commands, the per-cycle `History` (`hilrig.engine.history`), and the frame link the PDOs travel on
(`hilrig.wire.transport`).

A driver's small interface (what `Rig` uses): `configure()` after the node's PDO configuration was
read, `step()` -> `CycleResult`, `cycle`, `t`, `period_us`, `history`, `node_entered(state)`,
`poll()` (dispatch what arrived between cycles), `set_rpdo_value`, `latest`. The hardware is a
`hilrig.plants.interface.Plant`: its sensor fields go out in the sensor RPDO(s), its actuator
fields come from the TPDOs that carry them. The lockstep driver
(`hilrig.engine.lockstep`) waits for every TPDO due at its SYNC; the real-time one (`hilrig.engine.realtime`)
keeps a wall-clock period and takes what has arrived.
"""

from __future__ import annotations

import numbers
import operator
import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from boardproto.cia301 import (
    SYNC_COB_ID,
    SYNC_COUNTER_MAX,
    ErrorBehaviour,
    NmtState,
    emcy_cob_id,
    split_emcy,
    sync_counter,
)
from hilrig.engine.history import (
    History,
    HistoryBlock,
    HistoryMark,
    PdoRow,
    Value,
    resolve_truth_name,
)
from hilrig.errors import NoValueError, PdoMappingError
from hilrig.observe.paths import BUS_EVENTS_PATH
from hilrig.plants.interface import Plant
from hilrig.table import EmcyCode
from hilrig.wire.node import BoardNode
from hilrig.wire.transport import (
    Decoder,
    Exchange,
    FrameLink,
    PdoDirection,
    PdoLayout,
    SyncStarts,
    can_frame,
    due_table,
    exchanger,
    send_frames,
)

LIVENESS_SLICE_S = 0.25
"""While waiting for TPDOs, check this often (wall clock) whether the firmware still lives."""


SensorFrame = Any
"""A plant's sensor readings of one cycle (`Plant.sense`): an attribute per sensor field."""
Truth = Any
"""A plant's truth snapshot of one cycle (`Plant.truth`)."""
Outputs = tuple[Value, ...] | None
"""The plant's actuator fields of one cycle as the node sent them (None: it sent none)."""


FrameCallback = Callable[[int, bytes], None]
"""Called with (COB-ID, data) of a frame a driver's link received for a listener (`listen`)."""


@dataclass(frozen=True, slots=True)
class ProcessActivity:
    """What the kernel says a process is doing: CPU time used so far (all its threads), and
    whether it is asleep (blocked, waiting for an event) right now."""

    cpu_s: float
    sleeping: bool


_CLOCK_TICKS = os.sysconf("SC_CLK_TCK")


def process_activity(pid: int) -> ProcessActivity | None:
    """`pid`'s activity from /proc/PID/stat; None once it is gone or where /proc has no such
    file (the guard then falls back to wall time)."""
    return _stat_activity(f"/proc/{pid}/stat")


def thread_activity(native_id: int) -> ProcessActivity | None:
    """One thread of this process (`threading.get_native_id()`), from /proc/self/task/TID/stat:
    an in-process node's receive thread, so the hang guard judges a fake node as it judges a
    firmware process (a starved host is no verdict on either)."""
    return _stat_activity(f"/proc/self/task/{native_id}/stat")


def _stat_activity(stat_path: str) -> ProcessActivity | None:
    try:
        with open(stat_path, "rb") as stat:
            text = stat.read()
    except OSError:
        return None
    # The command name is in parentheses and may hold anything: fields follow the last ')'.
    fields = text[text.rfind(b")") + 2 :].split()
    try:
        state, utime, stime = fields[0], int(fields[11]), int(fields[12])
    except (IndexError, ValueError):
        return None
    if state in (b"Z", b"X"):
        # Exited, its entry not yet gone: a joined thread's task lingers a moment (seen on a
        # busy host), a process until it is reaped. Gone, as far as activity goes.
        return None
    return ProcessActivity((utime + stime) / _CLOCK_TICKS, state in (b"S", b"I"))


SYNC_FRAMES = tuple(can_frame(SYNC_COB_ID, bytes([counter])) for counter in range(1, SYNC_COUNTER_MAX + 1))
"""The SYNC frame of each counter value 1..240 (index counter - 1; cycle n's: index
n % SYNC_COUNTER_MAX, as `sync_counter(n)` counts)."""


def sync_frame(counter: int) -> bytes:
    """The SYNC frame with `counter` (1..240); `SYNC_FRAMES[counter - 1]` without the check."""
    if not 1 <= counter <= SYNC_COUNTER_MAX:
        raise ValueError(f"SYNC counter: expected 1..{SYNC_COUNTER_MAX}, got {counter}")
    return SYNC_FRAMES[counter - 1]


def sdo_poll_layout(names: tuple[str, ...], formats: tuple[str, ...]) -> PdoLayout:
    """The history's row layout of fields read over SDO (`Rig.poll_over_sdo`): a TPDO-like
    record with no COB-ID (number 0, disabled) and each field's `struct` code, so it is stored
    and traced like received PDOs."""
    return PdoLayout(
        direction=PdoDirection.TPDO,
        number=0,
        cob_id=0,
        enabled=False,
        transmission_type=255,
        names=names,
        formats=formats,
    )


# --- One cycle's result ---------------------------------------------------------------------
class CycleResult:
    """What one cycle (lockstep) or tick (real time) exchanged (treat it as read-only).

    received_rows: the TPDOs' rows; or, with `tpdos` (COB-ID -> layout), the decoded values by
    COB-ID as the lockstep exchange collects them, made into rows only when asked for (most
    cycles nobody asks: the history has them already)."""

    __slots__ = (
        "_dicts",
        "_received",
        "_tpdos",
        "cycle",
        "outputs",
        "raw",
        "sent_rows",
        "sync_counter",
        "time_s",
        "truth",
    )

    def __init__(
        self,
        cycle: int,
        time_s: float,
        sync_counter: int,
        raw: SensorFrame | None,
        received_rows: tuple[PdoRow, ...] | Mapping[int, tuple[Value, ...]],
        outputs: Outputs,
        sent_rows: tuple[PdoRow, ...] = (),
        truth: Truth | None = None,
        tpdos: Mapping[int, PdoLayout] | None = None,
    ) -> None:
        self.cycle = cycle
        self.time_s = time_s
        self.sync_counter = sync_counter
        self.raw = raw
        """None when no sensor frame was sampled (real time, physics off)."""
        self._received = received_rows
        self._tpdos = tpdos
        self.outputs = outputs
        """The plant's actuator fields the cycle applies (`Plant.apply`); None: none came."""
        self.sent_rows = sent_rows
        self.truth = truth
        """The plant state the cycle's sensor frame was sampled from (None without physics)."""
        self._dicts: dict[str, dict[str, Value]] | None = None

    @property
    def received_rows(self) -> tuple[PdoRow, ...]:
        if self._tpdos is not None:
            tpdos = self._tpdos
            got = self._received
            assert isinstance(got, Mapping)
            self._received = tuple([(tpdos[cob_id], values) for cob_id, values in got.items()])
            self._tpdos = None
        return self._received  # type: ignore[return-value]

    def values_by_cob_id(self) -> Mapping[int, tuple[Value, ...]]:
        """The received TPDOs' values by COB-ID: the lockstep exchange's own dict as it collected
        them (no copy, nothing built: what a checker of every cycle reads), or made from the rows."""
        got = self._received
        if type(got) is dict:  # the exchange's (an isinstance of Mapping costs more than the rest)
            return got
        if isinstance(got, Mapping):
            return got
        return {pdo.cob_id: values for pdo, values in got}  # type: ignore[union-attr]

    @property
    def received(self) -> dict[str, Value]:
        """TPDO values by name (built on first use)."""
        return self._merged("received", self.received_rows)

    @property
    def sent(self) -> dict[str, Value]:
        """RPDO values by name (built on first use)."""
        return self._merged("sent", self.sent_rows)

    def _merged(self, which: str, rows: tuple[PdoRow, ...]) -> dict[str, Value]:
        if self._dicts is None:
            self._dicts = {}
        if which not in self._dicts:
            self._dicts[which] = _merge(rows)
        return self._dicts[which]

    def __repr__(self) -> str:
        return (
            f"CycleResult(cycle={self.cycle}, time_s={self.time_s}, sync_counter={self.sync_counter}, "
            f"received_rows={self.received_rows!r}, outputs={self.outputs}, sent_rows={self.sent_rows!r})"
        )


def _merge(rows: Iterable[PdoRow]) -> dict[str, Value]:
    merged: dict[str, Value] = {}
    for pdo, values in sorted(rows, key=lambda row: row[0].number):
        merged.update(zip(pdo.names, values, strict=True))
    return merged


# --- The shared driver ----------------------------------------------------------------------
class Driver:
    """The node's PDO roles and the rig's RPDO values, over the node's frame link.

    `configure()` (after the node's PDO configuration was read) checks the mapping the driver
    relies on and compiles the per-cycle work: which RPDOs carry the plant's sensor fields and
    the setpoint stream, where the plant's actuator fields are, which TPDOs are due at which SYNC.
    `node_entered(state)` must follow every NMT command the rig sends, since the node counts
    SYNCs for its TPDOs from the moment it became operational.

    `keep_history=False`: the history records nothing (`History.keep`), for a run of millions of
    cycles that is judged as it goes. `listen` hands the frames of other COB-IDs the node sends
    (its heartbeat, its EMCY) to a callback as they arrive, on the driver's thread.
    """

    needs_sync_actuator = True
    """Whether configure() requires the actuator TPDO to be synchronous type 1."""

    def __init__(
        self,
        node: BoardNode,
        plant: Plant,
        *,
        period_us: int,
        tpdo_timeout_s: float = 5.0,
        liveness: Callable[[], None] | None = None,
        activity: Callable[[], ProcessActivity | None] | None = None,
        keep_history: bool = True,
    ) -> None:
        if period_us <= 0:
            raise ValueError(f"period_us: expected > 0, got {period_us}")
        self.node = node
        self.plant = plant
        self.period_us = period_us
        self.period_s = period_us / 1e6
        """The period in seconds (what the plant is stepped by every cycle)."""
        self.tpdo_timeout_s = tpdo_timeout_s
        self.liveness = liveness
        self.activity = activity
        """The node's process activity (`hilrig.engine.lockstep.process_activity`), for the hang
        guard to tell a busy host from a stuck firmware; None: wall time only."""
        self.history = History(period_us, keep=keep_history, plant=plant)
        self.cycle = 0
        """Cycles completed; also the index of the next cycle."""
        self.sensor_override: Callable[[SensorFrame], SensorFrame] | None = None
        """Fault injection hook: gets each cycle's raw sensors, returns what is sent."""
        self.paused_rpdos: set[int] = set()
        """RPDO numbers not sent at all (e.g. a silent setpoint stream for the watchdog)."""
        self.malformed_frames = 0
        """Frames on a TPDO's COB-ID whose length is not the mapping's (counted, dropped)."""
        self._link: FrameLink | None = None
        self._operational = False
        self._syncs_since_operational = 0
        self._rpdo_values: dict[int, list[Value]] = {}
        self._rpdo_frames: dict[int, tuple[PdoLayout, bytes, tuple[Value, ...]]] = {}
        """RPDO number -> (layout, frame, values): packed once per change, sent every cycle."""
        self._steady_stream: tuple[bytes, tuple[PdoRow, ...]] | None = None
        """The setpoint stream's frames (joined) and rows as `_rpdos_of_cycle` last sent them: what
        every cycle sends again while no RPDO changed (None: work it out again)."""
        self._stream_order: list[int] = []  # the setpoint stream's RPDOs, in sending order
        self._sensor_rpdos: list[tuple[PdoLayout, Callable[[SensorFrame], tuple[Value, ...]]]] = []
        self._stream_rpdos: set[int] = set()
        self._dirty_rpdos: set[int] = set()
        self._field_rpdo: dict[str, tuple[int, int]] = {}  # name -> (RPDO number, position)
        self._rpdo_layouts: dict[int, PdoLayout] = {}
        self._tpdo_by_cob: dict[int, PdoLayout] = {}
        self._emcy_cob_id = emcy_cob_id(node.node_id)
        self._actuator: Callable[[Mapping[int, tuple[Value, ...]]], Outputs] = _no_outputs
        """A cycle's TPDO values by COB-ID -> the plant's actuator fields (None: not all came)."""
        self._actuator_pdos: tuple[PdoLayout, ...] = ()
        self._actuator_one: tuple[int, int] | None = None
        """(COB-ID, position) of a plant's one actuator field: what a lockstep cycle reads
        itself, without `_actuator`'s call (the usual case); None: call `_actuator`."""
        self._due_table: list[frozenset[int]] = [frozenset()]
        """COB-IDs of the TPDOs due at each SYNC number modulo the table's length."""
        self._sync_starts: SyncStarts | None = None
        """The TPDOs with a SYNC start value; None when there are none (the usual case: a
        cycle then asks nothing more)."""
        self._decoders: dict[int, Decoder] = {}
        """COB-ID -> (length, unpack, cycles, payloads) of every enabled TPDO: what a cycle's
        exchange decodes, and the history's rows it appends each one to (`History.row_store`);
        (length, unpack) when the history keeps nothing."""
        self._rpdo_rows: dict[int, tuple[bytearray, bytearray]] = {}
        """COB-ID -> (cycles, payloads) of each enabled RPDO's sent rows in the history, which a
        lockstep cycle files the frames it sent into (`transport.append_frame_rows`)."""
        self._exchange: Exchange | None = None
        """`transport.exchange` bound to the link (configure())."""
        self._pending: list[tuple[int, bytes]] = []  # TPDO frames polled between cycles
        self._tpdo_names: frozenset[str] = frozenset()
        self._listeners: dict[int, list[FrameCallback]] = {}
        self._shared_poll: Callable[[float], None] | None = None
        """Set while the driver takes part in a shared link (`share_link`)."""

    @property
    def needs_plant_io(self) -> bool:
        """Whether configure() requires the sensor RPDO(s) and the actuator TPDO(s)."""
        return True

    @property
    def t(self) -> float:
        """Simulation time: cycles completed * period, exact."""
        return self.history.time_of(self.cycle)

    @property
    def link(self) -> FrameLink:
        if self._link is None:
            raise RuntimeError("the driver is not configured yet (Rig.start() configures it)")
        return self._link

    # --- Configuration ------------------------------------------------------------------
    def configure(self) -> None:
        """Work out which PDOs carry what, from the node's mapping; PdoMappingError if the
        plant's sensor inputs, the setpoint stream or its actuator outputs are not where they
        must be."""
        table = self.node.table
        problems: list[str] = []
        enabled_rpdos = [p for p in self.node.rpdos.values() if p.enabled and p.names]
        sensor_rpdos = [p for p in enabled_rpdos if any(table.is_hil_input(n) for n in p.names)]
        mapped_inputs = {n for p in sensor_rpdos for n in p.names}
        for name in self.plant.sensor_fields if self.needs_plant_io else ():
            if name not in mapped_inputs:
                problems.append(f"HIL input {name} is in no enabled RPDO")
        for pdo in sensor_rpdos:
            extra = [n for n in pdo.names if not table.is_hil_input(n)]
            if extra:
                problems.append(f"{pdo.label} mixes sensor inputs with {', '.join(extra)}")
        for cob_id in sorted({p.cob_id for p in enabled_rpdos}):
            sharing = [p.label for p in enabled_rpdos if p.cob_id == cob_id]
            if len(sharing) > 1:  # the node could not tell their frames apart, nor could the history
                problems.append(f"{' and '.join(sharing)} share a COB-ID")
        # The table's setpoint stream goes out every cycle, like a real master's (a board's
        # watchdog may watch it); each of its fields must be in an enabled RPDO. A board with
        # none has no stream: its RPDOs go out when a scenario changes a value.
        streamed = table.setpoint_stream
        stream = [p for p in enabled_rpdos if set(streamed) & set(p.names)]
        for name in streamed:
            if not any(name in p.names for p in stream):
                problems.append(f"setpoint {name} is in no enabled RPDO")
        enabled_tpdos = [p for p in self.node.tpdos.values() if p.enabled and p.names]
        actuator_at: list[tuple[PdoLayout, int]] = []
        for name in self.plant.actuator_fields:
            carrier = next((p for p in enabled_tpdos if name in p.names), None)
            if carrier is None:
                if self.needs_plant_io:
                    problems.append(f"HIL output {name} is in no enabled TPDO")
                continue
            if self.needs_sync_actuator and carrier.transmission_type != 1:
                problems.append(
                    f"{carrier.label} carries {name} with transmission type "
                    f"{carrier.transmission_type}; lockstep needs 1 (every SYNC)"
                )
            actuator_at.append((carrier, carrier.names.index(name)))
        if problems:
            raise PdoMappingError(f"node 0x{self.node.node_id:02X} PDO mapping: " + "; ".join(problems))

        self._sensor_rpdos = [(p, _getter(p.names)) for p in sensor_rpdos]
        self._stream_rpdos = {p.number for p in stream}
        # Keep what a scenario already set (re-configuring after a reset must not undo it);
        # otherwise start from the table's defaults, which the firmware starts from too.
        previous = {
            name: self._rpdo_values[number][position] for name, (number, position) in self._field_rpdo.items()
        }
        self._rpdo_values, self._rpdo_frames, self._field_rpdo, self._rpdo_layouts = {}, {}, {}, {}
        self._steady_stream = None
        for pdo in enabled_rpdos:
            if pdo in sensor_rpdos:
                continue
            self._rpdo_layouts[pdo.number] = pdo
            self._rpdo_values[pdo.number] = [
                previous[n] if n in previous else wire_value(n, table.field(n).default, code)
                for n, code in zip(pdo.names, pdo.formats, strict=True)
            ]
            for position, name in enumerate(pdo.names):
                self._field_rpdo[name] = (pdo.number, position)
        self._stream_order = [number for number in self._rpdo_values if number in self._stream_rpdos]
        self._tpdo_by_cob = {p.cob_id: p for p in enabled_tpdos}
        self._tpdo_names = frozenset(n for p in enabled_tpdos for n in p.names)
        complete = len(actuator_at) == len(self.plant.actuator_fields)
        self._actuator = _outputs_getter(actuator_at) if complete and actuator_at else _no_outputs
        self._actuator_pdos = tuple(dict.fromkeys(pdo for pdo, _ in actuator_at)) if complete else ()
        one = complete and len(actuator_at) == 1
        self._actuator_one = (actuator_at[0][0].cob_id, actuator_at[0][1]) if one else None
        self._due_table = due_table(enabled_tpdos)
        starts = SyncStarts(enabled_tpdos)
        self._sync_starts = starts if starts else None
        keep = self.history.keep
        self._decoders = {
            p.cob_id: (p.length, p.codec.unpack, *self.history.row_store(p), self.history.arrival_store(p))
            if keep
            else (p.length, p.codec.unpack)
            for p in enabled_tpdos
        }
        self._rpdo_rows = {p.cob_id: self.history.row_store(p) for p in enabled_rpdos} if keep else {}
        self._link = self.node.open_link(self.receive_ids())
        self._exchange = exchanger(self._link)
        self._shared_poll = None
        self._pending.clear()

    def receive_ids(self) -> list[int]:
        """The COB-IDs the driver's link receives: its enabled TPDOs, its EMCY, its listeners'."""
        return [*self._tpdo_by_cob, self._emcy_cob_id, *self._listeners]

    def share_link(self, link: FrameLink, exchange: Exchange, poll: Callable[[float], None]) -> None:
        """Take part in a link several drivers share (a robot's: one raw socket for every
        module's frames) instead of the driver's own, which is closed: frames go out on `link`,
        and `poll()` calls `poll(timeout_s)` (the owner of the link reads it and hands each
        frame to the driver whose COB-ID it is: `accept_polled`). Until the next configure()."""
        if self._link is not None and self._link is not link:
            self._link.close()
        self._link = link
        self._exchange = exchange
        self._shared_poll = poll

    @property
    def shares_link(self) -> bool:
        """Whether the driver takes part in a shared link (`share_link`) now."""
        return self._shared_poll is not None

    def accept_polled(self, cob_id: int, data: bytes) -> None:
        """A frame of this driver's read between cycles: a TPDO is kept for the next cycle,
        anything else is dispatched now (what `poll` does with each frame)."""
        if cob_id in self._tpdo_by_cob:
            self._pending.append((cob_id, data))
        else:
            self._other_frame(cob_id, data)

    def rpdo_of(self, name: str) -> int | None:
        """Number of the (non-sensor) RPDO that carries `name`, None if no RPDO does."""
        where = self._field_rpdo.get(name)
        return where[0] if where is not None else None

    def tpdo_names(self) -> frozenset[str]:
        return self._tpdo_names

    def set_rpdo_value(self, name: str, value: Value) -> None:
        """Put `value` into the RPDO that carries `name`; it goes out with the next cycle."""
        number, position = self._field_rpdo[name]
        value = wire_value(name, value, self._rpdo_layouts[number].formats[position])
        self._rpdo_values[number][position] = value
        self._rpdo_frames.pop(number, None)
        if number in self._stream_rpdos:  # another RPDO (a gait's setpoint) leaves the stream as it is
            self._steady_stream = None
        self._dirty_rpdos.add(number)

    def resend_rpdos(self) -> None:
        """Send every commanded RPDO again with the next cycle, as a master does after its
        node rebooted (the node starts from defaults)."""
        self._dirty_rpdos.update(self._rpdo_values)

    def rpdo_value(self, name: str) -> Value:
        number, position = self._field_rpdo[name]
        return self._rpdo_values[number][position]

    def node_entered(self, state: NmtState) -> None:
        """Tell the driver the node's NMT state changed (the rig sent the command)."""
        self._operational = state is NmtState.OPERATIONAL
        self._syncs_since_operational = 0
        if self._sync_starts is not None:
            self._sync_starts.reset()

    @property
    def operational(self) -> bool:
        return self._operational

    def _heartbeat_event(self) -> None:
        """The node reported a heartbeat event (its EMCY heartbeat_error): it changes its NMT
        state right after, by its error behaviour 0x1029:01 (CiA 301), before that cycle's TPDOs,
        which then do not come."""
        behaviour = self.node.error_behaviour
        if behaviour is ErrorBehaviour.STOPPED:
            self.node_entered(NmtState.STOPPED)
        elif behaviour is ErrorBehaviour.PRE_OPERATIONAL and self._operational:
            self.node_entered(NmtState.PRE_OPERATIONAL)

    # --- Values -------------------------------------------------------------------------
    def latest(self, name: str) -> Value:
        """Latest value the node sent for `name` in a TPDO."""
        try:
            return self.history.latest_received(name)
        except KeyError:
            if name in self._tpdo_names:
                raise NoValueError(
                    f"no TPDO with {name} received yet (t = {self.t:.6g} s, cycle {self.cycle})"
                ) from None
            raise NoValueError(f"{name} is in no enabled TPDO") from None

    # --- Frames -------------------------------------------------------------------------
    def send_frame(self, cob_id: int, data: bytes) -> None:
        """Any raw frame on the node's bus now (fault injection: floods, malformed frames)."""
        self.link.send(can_frame(cob_id, data))

    def listen(self, cob_id: int, callback: FrameCallback) -> None:
        """Have `callback(cob_id, data)` called with every frame on `cob_id` (not a TPDO: e.g.
        the node's heartbeat, or its EMCY besides `BoardNode.on_emcy`) as the link receives
        it: during a cycle's exchange or a `poll`, on the driver's thread. Before configure():
        the link it opens receives that COB-ID too."""
        self._listeners.setdefault(cob_id, []).append(callback)

    def poll(self, timeout_s: float = 0.0) -> None:
        """Take in what arrived since the last cycle: EMCYs are dispatched now (to
        `BoardNode.on_emcy`, and any listener), TPDOs are kept for the next cycle. Without
        waiting, or up to `timeout_s` for a first frame (e.g. the node's heartbeat before the
        first cycle, with a listener on it)."""
        if self._link is None:
            return
        if self._shared_poll is not None:
            self._shared_poll(timeout_s)
            return
        recv = self._link.recv
        frame = recv(timeout_s)
        while frame is not None:
            self.accept_polled(*frame)
            frame = recv(0.0)

    def take_late_tpdos(self) -> list[tuple[PdoLayout, bytes]]:
        """`poll`, then hand the TPDO frames that arrived since the last cycle to the caller
        instead of keeping them for the next one (which would refuse each: between SYNCs):
        after a cycle whose due TPDOs did not all come, these are the ones that came late."""
        self.poll()
        pending, self._pending = self._pending, []
        return [(self._tpdo_by_cob[cob_id], data) for cob_id, data in pending]

    def _other_frame(self, cob_id: int, data: bytes) -> None:
        if cob_id == self._emcy_cob_id:
            self.node.emcy_received(data)
            if split_emcy(data).code == EmcyCode.HEARTBEAT_ERROR:
                self._heartbeat_event()
        listeners = self._listeners.get(cob_id)
        if listeners is not None:
            for callback in listeners:
                callback(cob_id, data)

    def _transmit_rpdos(self, raw: SensorFrame | None) -> tuple[PdoRow, ...]:
        """Send one cycle's RPDOs (`_rpdos_of_cycle`) now; return what was sent."""
        sent, frames = self._rpdos_of_cycle(raw)
        if frames:
            send_frames(self.link, frames)
        return sent

    def _rpdos_of_cycle(self, raw: SensorFrame | None) -> tuple[tuple[PdoRow, ...], bytes]:
        """One cycle's RPDOs (the sensor frame from `raw` unless None, the setpoint stream, any
        RPDO a scenario changed): what they carry, and their frames joined, in sending order (the
        caller sends them: `send_frames`, or ahead of the SYNC in a cycle's exchange)."""
        frames = b""
        sent: list[PdoRow] = []
        paused = self.paused_rpdos
        if raw is not None:
            for pdo, values_of in self._sensor_rpdos:
                if paused and pdo.number in paused:
                    continue
                values = values_of(raw)
                frames += pdo.frame(values)
                sent.append((pdo, values))
        dirty, steady = self._dirty_rpdos, self._steady_stream
        if steady is not None and not dirty and not paused:
            # Most cycles send the setpoint stream alone, unchanged since it was last packed.
            return (*sent, *steady[1]), frames + steady[0]
        stream, packed = self._stream_rpdos, self._rpdo_frames
        for number in self._rpdo_values if dirty else self._stream_order:
            if number in paused or not (number in stream or number in dirty):
                continue
            entry = packed.get(number)
            if entry is None:
                pdo, values = self._rpdo_layouts[number], tuple(self._rpdo_values[number])
                entry = packed[number] = (pdo, pdo.frame(values), values)
            frames += entry[1]
            sent.append((entry[0], entry[2]))
            dirty.discard(number)
        if not paused and self._steady_stream is None:  # every stream RPDO is packed now
            stream_entries = [packed[number] for number in self._stream_order]
            self._steady_stream = (
                b"".join(e[1] for e in stream_entries),
                tuple((e[0], e[2]) for e in stream_entries),
            )
        return tuple(sent), frames

    def _decode(self, pdo: PdoLayout, data: bytes) -> tuple[Value, ...] | None:
        """The TPDO's values, or None (counted) when the frame's length is not the mapping's."""
        if len(data) != pdo.length:
            self.malformed_frames += 1
            return None
        return pdo.unpack(data)


def wire_value(name: str, value: Value, code: str) -> Value:
    """`value` as an RPDO carries `name` (its struct code): a whole number for an integer field
    (the table's defaults are floats: 0.0 for target_position), else ValueError naming the field;
    a float field takes it as it is."""
    if code in "efd" or isinstance(value, numbers.Integral):
        return value
    if isinstance(value, float) and value.is_integer():
        return int(value)
    raise ValueError(f"{name}: an integer field, got {value!r}")


def _getter(names: tuple[str, ...]) -> Callable[[SensorFrame], tuple[Value, ...]]:
    """Values of `names` from a plant's sensor frame, always as a tuple."""
    get = operator.attrgetter(*names)
    if len(names) == 1:
        return lambda raw: (get(raw),)
    return get  # type: ignore[return-value]


TpdoValues = Mapping[int, tuple[Value, ...]]
"""A cycle's TPDO values by COB-ID."""


def _no_outputs(_got: TpdoValues) -> Outputs:
    """The actuator getter of a node whose mapping carries no (or not every) actuator field."""
    return None


def _outputs_getter(at: Sequence[tuple[PdoLayout, int]]) -> Callable[[TpdoValues], Outputs]:
    """A cycle's TPDO values by COB-ID -> the actuator fields at (TPDO, position) each, as a
    tuple, or None when a TPDO carrying one did not come (one lookup for the usual one field)."""
    if len(at) == 1:
        cob_id, position = at[0][0].cob_id, at[0][1]

        def one(got: Mapping[int, tuple[Value, ...]]) -> Outputs:
            values = got.get(cob_id)
            return None if values is None else (values[position],)

        return one
    where = [(pdo.cob_id, position) for pdo, position in at]

    def several(got: Mapping[int, tuple[Value, ...]]) -> Outputs:
        try:
            return tuple([got[cob_id][position] for cob_id, position in where])
        except KeyError:
            return None

    return several


__all__ = [
    "BUS_EVENTS_PATH",
    "SYNC_FRAMES",
    "CycleResult",
    "Driver",
    "FrameCallback",
    "History",
    "HistoryBlock",
    "HistoryMark",
    "Outputs",
    "PdoRow",
    "Plant",
    "SensorFrame",
    "Truth",
    "resolve_truth_name",
    "sdo_poll_layout",
    "sync_counter",
    "sync_frame",
]
