"""The lockstep driver: the rig is the SYNC producer and each SYNC is one control cycle.

One cycle (index n, simulation time t = n * period, exact):

1. sample the plant: raw sensor values (`RawSensors`) -> the RPDO(s) mapping the HIL inputs;
2. send the setpoint stream (the RPDO carrying velocity_setpoint, every cycle like a real
   master; the firmware's watchdog watches it) and any other RPDO a scenario changed;
3. send SYNC with counter (n mod 240) + 1;
4. wait for every synchronous TPDO due at this SYNC (type k: every k-th SYNC since the node
   entered operational); the wall-clock bound is only a hang guard;
5. step the plant by one period with the duty from the actuator TPDO (motor_duty).

Every cycle's received values, sent values and the plant's ground truth go into `History`.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np

from hilrig.errors import FirmwareError, LockstepError, NoValueError, PdoMappingError
from hilrig.node import SYNC_COUNTER_MAX, BoardNode, NmtState, PdoLayout
from hilrig.physics import JointPlant, JointState, RawSensors, SensorModel, duty_from_motor_duty
from hilrig.table import unknown_name

Value = float | int

ACTUATOR_OUTPUT = "motor_duty"
"""The HIL output that drives the plant; its TPDO must be synchronous type 1."""
SETPOINT_STREAM = ("velocity_setpoint", "torque_setpoint")
"""Fields of the RPDO sent every cycle, like a real master's setpoint stream."""
_LIVENESS_SLICE_S = 0.25
"""While waiting for TPDOs, check this often (wall clock) whether the firmware still lives."""

TRUTH_NAMES: tuple[str, ...] = tuple(name for name in JointState.__dataclass_fields__ if name != "time_s")
"""Ground-truth quantities, named as the JointState attributes (unit in the name)."""
_UNIT_SUFFIXES = ("_rad_s", "_rad", "_nm", "_a", "_c", "_ohm")
TRUTH_ALIASES: dict[str, str] = {
    name[: -len(suffix)]: name for name in TRUTH_NAMES for suffix in _UNIT_SUFFIXES if name.endswith(suffix)
}
"""Short names without the unit suffix ("load_velocity" -> "load_velocity_rad_s")."""


def sync_counter(cycle: int) -> int:
    """The SYNC counter of cycle index `cycle` (0-based): 1..240, wrapping."""
    return cycle % SYNC_COUNTER_MAX + 1


@dataclass
class _Series:
    """One named signal: the cycles it has a value in, and the values. Cheap to append."""

    cycles: list[int] = field(default_factory=list)
    values: list[Value] = field(default_factory=list)

    def append(self, cycle: int, value: Value) -> None:
        self.cycles.append(cycle)
        self.values.append(value)


class History:
    """Per-cycle record of what the node sent, what the rig sent, and the plant's truth.

    Times are cycle * period exactly: the start of the cycle whose SYNC the values belong to.
    Truth rows hold the plant state at that time (the one the cycle's sensor frame was
    sampled from).
    """

    def __init__(self, period_us: int) -> None:
        self.period_us = period_us
        self._received: dict[str, _Series] = {}
        self._sent: dict[str, _Series] = {}
        self._truth: list[JointState] = []

    def time_of(self, cycle: int) -> float:
        return cycle * self.period_us / 1e6

    def _times(self, cycles: Iterable[int]) -> np.ndarray:
        return np.fromiter(cycles, dtype=np.int64) * self.period_us / 1e6

    @property
    def cycles(self) -> int:
        return len(self._truth)

    def record_truth(self, state: JointState) -> None:
        self._truth.append(state)

    def record_received(self, cycle: int, values: Mapping[str, Value]) -> None:
        for name, value in values.items():
            self._received.setdefault(name, _Series()).append(cycle, value)

    def record_sent(self, cycle: int, values: Mapping[str, Value]) -> None:
        for name, value in values.items():
            self._sent.setdefault(name, _Series()).append(cycle, value)

    def has_received(self, name: str) -> bool:
        return name in self._received

    def has_sent(self, name: str) -> bool:
        return name in self._sent

    def received(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """(t, values) of every cycle a TPDO carried `name`."""
        series = self._received[name]
        return self._times(series.cycles), np.asarray(series.values)

    def sent(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """(t, values) of every cycle the rig sent `name` in an RPDO."""
        series = self._sent[name]
        return self._times(series.cycles), np.asarray(series.values)

    def latest_received(self, name: str) -> Value:
        return self._received[name].values[-1]

    def truth(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """(t, values) of a ground-truth quantity (JointState attribute or its short alias)."""
        attribute = resolve_truth_name(name)
        values = np.fromiter(
            (getattr(s, attribute) for s in self._truth), dtype=float, count=len(self._truth)
        )
        return self._times(range(len(self._truth))), values


def resolve_truth_name(name: str) -> str:
    if name in TRUTH_NAMES:
        return name
    if name in TRUTH_ALIASES:
        return TRUTH_ALIASES[name]
    raise unknown_name("ground-truth quantity", name, (*TRUTH_NAMES, *TRUTH_ALIASES))


class _TpdoInbox:
    """Collects the TPDOs of the cycle in progress; filled by canopen's receive thread."""

    def __init__(self) -> None:
        self._condition = threading.Condition()
        self._due: dict[int, PdoLayout] = {}
        self._got: dict[int, dict[str, Value]] = {}
        self._problems: list[str] = []
        self._open = False
        self._sync_number = 0

    def open(self, due: Iterable[PdoLayout], sync_number: int) -> None:
        with self._condition:
            self._due = {pdo.number: pdo for pdo in due}
            self._open = True
            self._sync_number = sync_number

    def deliver(self, pdo: PdoLayout, values: dict[str, Value]) -> None:
        with self._condition:
            cyclic = pdo.is_synchronous and pdo.transmission_type >= 1
            if pdo.number in self._got and cyclic:
                self._problems.append(f"{pdo.label} arrived twice")
            elif cyclic and (not self._open or pdo.number not in self._due):
                self._problems.append(
                    f"{pdo.label} arrived but is not due at SYNC {self._sync_number} since "
                    f"operational (transmission type {pdo.transmission_type})"
                )
            self._got[pdo.number] = values
            if self._complete():  # wake the waiting loop once per cycle, not once per frame
                self._condition.notify_all()

    def _complete(self) -> bool:
        return bool(self._problems) or self._due.keys() <= self._got.keys()

    def wait(self, timeout_s: float, liveness: Callable[[], None] | None) -> list[PdoLayout]:
        """Wait until every due TPDO is in; return the ones still missing (empty when done)."""
        deadline = time.monotonic() + timeout_s
        with self._condition:
            while not self._complete():
                remaining = deadline - time.monotonic()
                if remaining <= 0.0:
                    break
                self._condition.wait_for(self._complete, min(remaining, _LIVENESS_SLICE_S))
                if liveness is not None and not self._complete():
                    self._condition.release()
                    try:
                        liveness()  # raises (e.g. FirmwareError) when the node's process died
                    finally:
                        self._condition.acquire()
            return [pdo for n, pdo in sorted(self._due.items()) if n not in self._got]

    def take(self) -> tuple[dict[int, dict[str, Value]], list[str]]:
        """Close the cycle: hand over what arrived and any problems, start empty."""
        with self._condition:
            got, problems = self._got, self._problems
            self._got, self._problems, self._due, self._open = {}, [], {}, False
            return got, problems


@dataclass(frozen=True)
class CycleResult:
    """What one lockstep cycle exchanged."""

    cycle: int
    time_s: float
    sync_counter: int
    raw: RawSensors | None  # None when no sensor frame was sampled (real time, physics off)
    received: dict[str, Value]
    duty: float
    sent: dict[str, Value] = field(default_factory=dict)  # RPDO values of this cycle (for hilrig.trace)


class LockstepDriver:
    """Runs lockstep cycles between a `BoardNode` and the joint plant.

    Call `configure()` after the node's PDO configuration was read; it checks the mapping the
    driver relies on. `node_entered(state)` must follow every NMT command the rig sends, since
    the node counts SYNCs for its TPDOs from the moment it became operational.
    """

    needs_sync_actuator = True
    """Whether configure() requires the actuator TPDO to be synchronous type 1."""

    def __init__(
        self,
        node: BoardNode,
        plant: JointPlant,
        sensors: SensorModel,
        *,
        period_us: int = 1000,
        tpdo_timeout_s: float = 5.0,
        liveness: Callable[[], None] | None = None,
    ) -> None:
        if period_us <= 0:
            raise ValueError(f"period_us: expected > 0, got {period_us}")
        self.node = node
        self.plant = plant
        self.sensors = sensors
        self.period_us = period_us
        self.tpdo_timeout_s = tpdo_timeout_s
        self.liveness = liveness
        self.history = History(period_us)
        self.cycle = 0
        """Cycles completed; also the index of the next cycle."""
        self.sensor_override: Callable[[RawSensors], RawSensors] | None = None
        """Fault injection hook: gets each cycle's raw sensors, returns what is sent."""
        self.paused_rpdos: set[int] = set()
        """RPDO numbers not sent at all (e.g. a silent setpoint stream for the watchdog)."""
        self._inbox = _TpdoInbox()
        self._operational = False
        self._syncs_since_operational = 0
        self._rpdo_values: dict[int, dict[str, Value]] = {}
        self._sensor_rpdos: list[PdoLayout] = []
        self._stream_rpdos: list[PdoLayout] = []
        self._dirty_rpdos: set[int] = set()
        self._field_rpdo: dict[str, int] = {}
        self._cyclic_tpdos: list[PdoLayout] = []
        self._latest: dict[str, Value] = {}
        self._lock = threading.Lock()  # guards _latest against readers in other threads
        node.on_tpdo(self._on_tpdo)

    @property
    def period_s(self) -> float:
        return self.period_us / 1e6

    @property
    def needs_plant_io(self) -> bool:
        """Whether configure() requires the sensor RPDO(s) and the actuator TPDO."""
        return True

    def _on_tpdo(self, pdo: PdoLayout, values: dict[str, Value]) -> None:
        """canopen's receive thread hands over each TPDO here."""
        self._inbox.deliver(pdo, values)

    @property
    def t(self) -> float:
        """Simulation time: cycles completed * period, exact."""
        return self.history.time_of(self.cycle)

    # --- Configuration ------------------------------------------------------------------
    def configure(self) -> None:
        """Work out which PDOs carry what, from the node's mapping; PdoMappingError if the
        sensor inputs, the setpoint stream or the actuator output is not where it must be."""
        table = self.node.table
        problems: list[str] = []
        enabled_rpdos = [p for p in self.node.rpdos.values() if p.enabled and p.names]
        self._sensor_rpdos = [p for p in enabled_rpdos if any(table.is_hil_input(n) for n in p.names)]
        mapped_inputs = {n for p in self._sensor_rpdos for n in p.names}
        for io in table.board.hil_inputs if self.needs_plant_io else ():
            if io.name not in mapped_inputs:
                problems.append(f"HIL input {io.name} is in no enabled RPDO")
        for pdo in self._sensor_rpdos:
            extra = [n for n in pdo.names if not table.is_hil_input(n)]
            if extra:
                problems.append(f"{pdo.label} mixes sensor inputs with {', '.join(extra)}")
        self._stream_rpdos = [p for p in enabled_rpdos if set(SETPOINT_STREAM) & set(p.names)]
        for name in SETPOINT_STREAM:
            if not any(name in p.names for p in self._stream_rpdos):
                problems.append(f"setpoint {name} is in no enabled RPDO")
        # Keep what a scenario already set (re-configuring after a reset must not undo it);
        # otherwise start from the table's defaults, which the firmware starts from too.
        previous = {n: v for values in self._rpdo_values.values() for n, v in values.items()}
        self._rpdo_values = {}
        self._field_rpdo = {}
        for pdo in enabled_rpdos:
            if pdo in self._sensor_rpdos:
                continue
            self._rpdo_values[pdo.number] = {n: previous.get(n, table.field(n).default) for n in pdo.names}
            for name in pdo.names:
                self._field_rpdo[name] = pdo.number
        actuator = [p for p in self.node.tpdos.values() if p.enabled and ACTUATOR_OUTPUT in p.names]
        if not actuator:
            if self.needs_plant_io:
                problems.append(f"HIL output {ACTUATOR_OUTPUT} is in no enabled TPDO")
        elif self.needs_sync_actuator and actuator[0].transmission_type != 1:
            problems.append(
                f"{actuator[0].label} carries {ACTUATOR_OUTPUT} with transmission type "
                f"{actuator[0].transmission_type}; lockstep needs 1 (every SYNC)"
            )
        if problems:
            raise PdoMappingError(f"node 0x{self.node.node_id:02X} PDO mapping: " + "; ".join(problems))
        self._cyclic_tpdos = [
            p for p in self.node.tpdos.values() if p.enabled and 1 <= p.transmission_type <= 240
        ]

    def rpdo_of(self, name: str) -> int | None:
        """Number of the (non-sensor) RPDO that carries `name`, None if no RPDO does."""
        return self._field_rpdo.get(name)

    def tpdo_names(self) -> set[str]:
        return {n for p in self.node.tpdos.values() if p.enabled for n in p.names}

    def set_rpdo_value(self, name: str, value: Value) -> None:
        """Put `value` into the RPDO that carries `name`; it goes out with the next cycle."""
        number = self._field_rpdo[name]
        self._rpdo_values[number][name] = value
        self._dirty_rpdos.add(number)

    def resend_rpdos(self) -> None:
        """Send every commanded RPDO again with the next cycle, as a master does after its
        node rebooted (the node starts from defaults)."""
        self._dirty_rpdos.update(self._rpdo_values)

    def rpdo_value(self, name: str) -> Value:
        return self._rpdo_values[self._field_rpdo[name]][name]

    def node_entered(self, state: NmtState) -> None:
        """Tell the driver the node's NMT state changed (the rig sent the command)."""
        self._operational = state is NmtState.OPERATIONAL
        self._syncs_since_operational = 0

    @property
    def operational(self) -> bool:
        return self._operational

    # --- Values -------------------------------------------------------------------------
    def latest(self, name: str) -> Value:
        """Latest value the node sent for `name` in a TPDO."""
        with self._lock:
            try:
                return self._latest[name]
            except KeyError:
                if name in self.tpdo_names():
                    raise NoValueError(
                        f"no TPDO with {name} received yet (t = {self.t:.6g} s, cycle {self.cycle})"
                    ) from None
                raise NoValueError(f"{name} is in no enabled TPDO") from None

    # --- One cycle ----------------------------------------------------------------------
    def step(self) -> CycleResult:
        n = self.cycle
        t = self.history.time_of(n)
        counter = sync_counter(n)
        state = self.plant.state
        raw = self.sensors.read(state)
        if self.sensor_override is not None:
            raw = self.sensor_override(raw)

        sync_number = self._syncs_since_operational + 1 if self._operational else 0
        due = [p for p in self._cyclic_tpdos if p.due_at_sync(sync_number)] if self._operational else []
        stray, problems = self._inbox.take()
        if problems:  # arrived after the last cycle closed: a late or duplicate frame
            raise self._error(n, t, "; ".join(problems) + " (between SYNCs)")
        self._inbox.open(due, sync_number)

        sent = self._transmit_rpdos(raw)
        self.node.send_sync(counter)
        if self._operational:
            self._syncs_since_operational += 1

        try:
            missing = self._inbox.wait(self.tpdo_timeout_s, self.liveness)
        except FirmwareError as error:  # the node's process died while this cycle waited
            raise FirmwareError(f"cycle {n} (t = {t:.6g} s): {error}") from error
        got, problems = self._inbox.take()
        if problems:
            raise self._error(n, t, "; ".join(problems))
        if missing:
            labels = ", ".join(p.label for p in missing)
            verb = "did" if len(missing) == 1 else "do"
            heartbeat = self.node.last_heartbeat
            hint = f"; last heartbeat: {heartbeat.name}" if heartbeat is not None else ""
            raise self._error(n, t, f"{labels} {verb} not arrive within {self.tpdo_timeout_s:g} s{hint}")

        received: dict[str, Value] = {}
        for number in sorted({*stray, *got}):
            received.update(stray.get(number, {}))
            received.update(got.get(number, {}))
        # Without the actuator TPDO (node not operational) the bridge is off, as a motor
        # driver whose command stream stopped would be.
        duty = duty_from_motor_duty(int(received[ACTUATOR_OUTPUT])) if ACTUATOR_OUTPUT in received else 0.0

        self.history.record_truth(state)
        self.history.record_sent(n, sent)
        self.history.record_received(n, received)
        with self._lock:
            self._latest.update(received)
        self.plant.step(self.period_s, duty)
        self.cycle = n + 1
        return CycleResult(
            cycle=n, time_s=t, sync_counter=counter, raw=raw, received=received, duty=duty, sent=sent
        )

    def _transmit_rpdos(self, raw: RawSensors | None) -> dict[str, Value]:
        """Send one cycle's RPDOs (the sensor frame from `raw` unless None, the setpoint
        stream, any RPDO a scenario changed); return the values sent, by name."""
        sent: dict[str, Value] = {}
        raw_values = raw.as_dict() if raw is not None else None
        for pdo in self._sensor_rpdos if raw_values is not None else ():
            if pdo.number in self.paused_rpdos:
                continue
            values = {name: raw_values[name] for name in pdo.names}
            self.node.transmit_rpdo(pdo.number, values)
            sent.update(values)
        for number, values in self._rpdo_values.items():
            streamed = any(p.number == number for p in self._stream_rpdos)
            if number in self.paused_rpdos or not (streamed or number in self._dirty_rpdos):
                continue
            self.node.transmit_rpdo(number, values)
            sent.update(values)
            self._dirty_rpdos.discard(number)
        return sent

    @staticmethod
    def _error(cycle: int, t: float, what: str) -> LockstepError:
        return LockstepError(f"cycle {cycle} (t = {t:.6g} s): {what}")


def cycles_for(seconds: float, period_us: int) -> int:
    """Whole cycles covering `seconds` (a hair over a whole number is float noise, not a cycle)."""
    if not (math.isfinite(seconds) and seconds >= 0.0):
        raise ValueError(f"seconds: expected finite >= 0, got {seconds}")
    exact = seconds * 1e6 / period_us
    nearest = round(exact)
    return nearest if abs(exact - nearest) < 1e-6 else math.ceil(exact)


__all__ = [
    "ACTUATOR_OUTPUT",
    "SETPOINT_STREAM",
    "TRUTH_ALIASES",
    "TRUTH_NAMES",
    "CycleResult",
    "History",
    "LockstepDriver",
    "cycles_for",
    "resolve_truth_name",
    "sync_counter",
]
