"""The scenario API: a lockstep rig around one board node, written to read like the test.

    with Rig(bus, params=JointParams.fast_thermal(), seed=1) as rig:
        rig.set("control_mode", ControlMode.VELOCITY)   # SDO, or the RPDO that carries it
        rig.set("velocity_setpoint", 10.0)      # goes out in the setpoint stream
        rig.at(0.5, lambda rig: rig.set("velocity_setpoint", 0.0))
        rig.run(seconds=1.0)
        t, v = rig.history("output_velocity")   # what the firmware reported, per cycle
        t, truth = rig.truth("load_velocity")   # what the physics did

Simulation time is exact (`rig.t == rig.cycle * period`); every timeout a scenario writes
is in simulation time. The bus is the caller's; the rig never opens one.

The same scenario runs in real time, against the firmware in `--mode free` or a real board:
`Rig(bus, mode="realtime", period_us=10_000)` keeps its own wall-clock period
(`hilrig.engine.realtime`), and `rig.t`, `run(seconds=...)`, `at()` and the histories are then in
wall seconds since the first tick. `physics=False` (bring-up of a real board): no plant, no
sensor frames; the rig only commands and observes.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Self

import can
import numpy as np
from canopen.emcy import EmcyError

from boardproto.cia301 import NmtCommand, NmtState, transmission_text
from hilrig import resources
from hilrig.engine.bustiming import SDO_ANSWER_TIMEOUT_S, BusTimeline, BusTiming, heartbeat_cycles
from hilrig.engine.driver import (
    BUS_EVENTS_PATH,
    CycleResult,
    Driver,
    ProcessActivity,
    SensorFrame,
    Truth,
    sdo_poll_layout,
)
from hilrig.engine.lockstep import LockstepDriver, cycles_for
from hilrig.engine.observers import RigObserver
from hilrig.engine.realtime import RealTimeDriver
from hilrig.engine.timeline import CycleRunner
from hilrig.engine.timing import TimingMode
from hilrig.errors import (
    FieldAccessError,
    LockstepError,
    NoValueError,
    RealTimeError,
    SdoAbortError,
    SdoTimeoutError,
)
from hilrig.plants import default_plant
from hilrig.plants.interface import Plant
from hilrig.table import RigTable
from hilrig.wire.bustime import TimedBus
from hilrig.wire.node import BoardNode, EmcyRecord

if TYPE_CHECKING:
    from hilrig.wire.transport import PdoLayout

DEFAULT_EDS_PATH = resources.DEFAULT_EDS
"""The EDS of the default table: the checkout's build/protocol/board.eds, or the wheel's copy."""


class Rig(CycleRunner):
    """Lockstep rig: the plant (`hilrig.plants.interface.Plant`) and one board node on the
    caller's bus.

    Construction connects to the bus (starts canopen's receive thread) but sends nothing;
    `start()` (or entering the `with` block) brings the node up: waits for its boot-up or
    heartbeat, checks its identity, reads and verifies its PDO mapping, puts it operational.

    bus: python-can bus the caller owns and shuts down. node_id: default from board.toml.
    eds: the generated EDS. plant: the hardware model; default: the demo joint
    (`hilrig.plants.default_plant`) of `params` (its parameters) and `seed` (its sensor noise).
    period_us: control period (the firmware's --period-us). liveness: called while waiting
    for the boot-up and for TPDOs, raises when the node's process died (e.g. `Firmware.check`). activity: the
    node's process activity (e.g. `Firmware.activity`), so that the lockstep hang guard tells a
    busy host from a stuck firmware. Timeouts in seconds of wall clock are hang guards only.
    tracer: a `hilrig.observe.tracer.Tracer` that gets every cycle, NMT change, EMCY and SDO abort (the
    caller closes it); it is an observer like any other (`add_observer`).
    mode: "lockstep" or "realtime" (`TimingMode`); in real time `period_us` is the rig's own
    tick, which need not equal the node's period. physics: False only in real time (observe
    and command a real board; `truth()` and `state` then have nothing to show).
    A robot's module gets its plant from the robot's chain, whose mechanics step every module
    together.
    """

    def __init__(
        self,
        bus: can.BusABC,
        *,
        node_id: int | None = None,
        eds: str | Path = DEFAULT_EDS_PATH,
        params: object | None = None,
        seed: int = 0,
        period_us: int | None = None,
        table: RigTable | None = None,
        liveness: Callable[[], None] | None = None,
        activity: Callable[[], ProcessActivity | None] | None = None,
        boot_timeout_s: float = 2.0,
        tpdo_timeout_s: float = 5.0,
        sdo_timeout_s: float = 1.0,
        tracer: RigObserver | None = None,
        mode: TimingMode | str = TimingMode.LOCKSTEP,
        physics: bool = True,
        plant: Plant | None = None,
        bitrate: int | None = None,
    ) -> None:
        self.mode = TimingMode(mode)  # a typo raises ValueError here, not mid-scenario
        self.physics = physics
        if not physics and self.mode is TimingMode.LOCKSTEP:
            raise ValueError(
                "physics=False needs mode='realtime': in lockstep the node waits for the physics"
            )
        self.table = table if table is not None else RigTable.load()
        if period_us is None:
            period_us = self.table.board.node.period_us
        self.boot_timeout_s = boot_timeout_s
        node_id = node_id if node_id is not None else self.table.board.node.default_node_id
        self.node = BoardNode(bus, node_id, eds, self.table, sdo_timeout_s=sdo_timeout_s)
        self.plant: Plant = plant if plant is not None else default_plant(params, seed)
        self.driver: Driver
        if self.mode is TimingMode.REALTIME:
            self.driver = RealTimeDriver(
                self.node,
                self.plant,
                period_us=period_us,
                physics=physics,
                tpdo_timeout_s=tpdo_timeout_s,
                liveness=liveness,
            )
        else:
            self.driver = LockstepDriver(
                self.node,
                self.plant,
                period_us=period_us,
                tpdo_timeout_s=tpdo_timeout_s,
                liveness=liveness,
                activity=activity,
            )
        if bitrate is not None and self.mode is not TimingMode.LOCKSTEP:
            raise ValueError("bitrate= times the lockstep bus; in real time the bus is the real one")
        self.bitrate = bitrate
        """The timed bus's bit rate (`hilrig.engine.bustiming`); None: the ideal bus."""
        self.liveness = liveness
        self._emcy: list[EmcyRecord] = []
        self._emcy_lock = threading.Lock()
        self._init_timeline()
        self.robot: object | None = None
        """The robot (`hilrig.engine.robot.Robot`) this rig is a module of: it steps the rig's driver."""
        self.node.on_emcy(self._on_emcy)
        self.observers: list[RigObserver] = []
        self._polled: tuple[PdoLayout, int] | None = None  # Rig.poll_over_sdo: (names, every)
        self._heartbeat_state: NmtState | None = None
        self._stepping = False  # inside a cycle (`_step`): an SDO there waits for no bus
        self.node.remote.nmt.add_heartbeat_callback(self._on_heartbeat_state)
        self.tracer = tracer
        if tracer is not None:
            self.add_observer(tracer)

    @property
    def bus_timeline(self) -> BusTimeline | None:
        """The timed bus's per-cycle load, backlog and late frames (None: the ideal bus)."""
        timing = getattr(self.driver, "bus_timing", None)
        return None if timing is None else timing.timeline

    def leave_timed_bus(self) -> BusTimeline | None:
        """The next cycles and SDO transfers on the ideal bus (a run's closing SDO reads for its
        summary, which the timed bus might never carry); returns the timed bus's timeline."""
        timeline = self.bus_timeline
        if timeline is not None:
            assert isinstance(self.driver, LockstepDriver)
            self.driver.time_bus(None)
            self.node.count_sdo_frames(None)
        return timeline

    def add_observer(self, observer: RigObserver) -> None:
        """Let `observer` watch every later cycle and event (`hilrig.engine.observers`)."""
        observer.on_plant(self.plant)
        observer.on_history(self.driver.history)
        if self._polled is not None:
            observer.on_polled(self._polled[0].names, self._polled[1])
        self.observers.append(observer)

    def in_no_pdo(self, names: Sequence[str]) -> list[str]:
        """Those of `names` that no TPDO or RPDO of the node's mapping carries (what a trace
        has only when read over SDO: `poll_over_sdo`)."""
        driver = self.driver
        tpdo_names = driver.tpdo_names()
        return [name for name in names if name not in tpdo_names and driver.rpdo_of(name) is None]

    def poll_over_sdo(self, names: Sequence[str], every_cycles: int) -> None:
        """Read these fields (which travel in no PDO) over SDO after every `every_cycles`-th
        cycle, into the history (`rig.history(name)`) and so into the trace, marked as polled.
        Each read is an SDO round trip between two cycles: in lockstep it costs wall time, not
        simulation time. Replaces an earlier poll; no names: stop polling."""
        if every_cycles < 1:
            raise ValueError(f"every_cycles: expected >= 1, got {every_cycles}")
        self.table.check(names)
        streamed = sorted(set(names) & self.driver.tpdo_names())
        if streamed:
            raise ValueError(f"{', '.join(streamed)}: in a TPDO already, every cycle it is due")
        if not names:
            self._polled = None
            return
        formats = tuple(self.table.entry(name).data_type.struct_code for name in names)
        self._polled = (sdo_poll_layout(tuple(names), formats), every_cycles)
        for observer in self.observers:
            observer.on_polled(tuple(names), every_cycles)

    def _poll(self, cycle: int) -> None:
        assert self._polled is not None
        layout, every = self._polled
        if cycle % every == 0:
            values = tuple(self.read(name) for name in layout.names)
            self.driver.history.record_rows(cycle, ((layout, values),), ())

    def log_event(self, path: str, text: str, *, warning: bool = True) -> None:
        """A line on the observers' timeline (e.g. an injected fault under /events/faults)."""
        for observer in self.observers:
            observer.on_event(path, text, warning=warning, cycle=self.cycle, t=self.t)

    # --- Life cycle ---------------------------------------------------------------------
    def start(self) -> None:
        """Bring the node up (bounded waits) and put it operational."""
        self.node.wait_until_alive(self.boot_timeout_s, liveness=self.liveness)
        self._configure_and_start()

    def _configure_and_start(self) -> None:
        self.node.check_identity()
        self.node.read_pdo_configuration(from_node=True)
        self.driver.configure()
        if self.bitrate is not None:
            assert isinstance(self.driver, LockstepDriver)
            heartbeat = heartbeat_cycles(self.table.board.node.heartbeat_ms, self.driver.period_us)
            self.driver.time_bus(TimedBus(self.bitrate, self.driver.period_us), heartbeat)
            timing = self.driver.bus_timing
            assert timing is not None
            self.node.count_sdo_frames(lambda cob_id, dlc: self._charge_sdo(timing, cob_id, dlc))
        self._log_pdo_configuration()
        for observer in self.observers:
            observer.on_configured(truth=self.physics)
        self.nmt(NmtCommand.START)

    def _log_pdo_configuration(self) -> None:
        """Which PDOs the node uses and when they go out, as read from it: the first lines of
        the bus's events (a PDO missing later is then read against them)."""
        node = self.node
        for pdo in (*node.tpdos.values(), *node.rpdos.values()):
            if pdo.enabled and pdo.names:
                when = transmission_text(pdo.transmission_type)
                self.log_event(BUS_EVENTS_PATH, f"{pdo.label}, {when}: {', '.join(pdo.names)}", warning=False)

    def restart_node(self, restart: Callable[[], object], *, boot_timeout_s: float | None = None) -> None:
        """Restart the node with `restart()` (e.g. `Firmware.restart`: kill and start the
        process), wait for its boot-up, read its PDO mapping again and put it operational.
        What was stored survives; what was only written by SDO is back to its default."""
        self.driver.node_entered(NmtState.INITIALISING)
        self.node.await_boot_up(
            restart, boot_timeout_s if boot_timeout_s is not None else self.boot_timeout_s
        )
        for observer in self.observers:
            observer.on_nmt(NmtState.INITIALISING, self.t, cycle=self.cycle, source="restart")
        self._configure_and_start()
        self.driver.resend_rpdos()

    def close(self) -> None:
        self.node.close()

    def __enter__(self) -> Self:
        try:
            self.start()
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, traceback: TracebackType | None
    ) -> None:
        self.close()

    # --- Time ---------------------------------------------------------------------------
    @property
    def cycle(self) -> int:
        """Cycles completed (the index of the next cycle)."""
        return self.driver.cycle

    @property
    def t(self) -> float:
        """Lockstep: simulation time [s] = cycle * period, exact. Real time: wall seconds
        from the first tick to the last one."""
        return self.driver.t

    @property
    def realtime(self) -> bool:  # type: ignore[override]
        return self.mode is TimingMode.REALTIME

    @property
    def period_s(self) -> float:
        return self.driver.period_s

    @property
    def period_us(self) -> int:
        return self.driver.period_us

    def _step(self) -> None:
        """One cycle (tick); the observers get its result."""
        if self.robot is not None:
            raise RuntimeError(
                f"node 0x{self.node.node_id:02X} is a module of a robot: run the robot, which "
                "steps all its modules around one SYNC"
            )
        self._stepping = True
        try:
            try:
                result = self.driver.step()
            except (LockstepError, RealTimeError) as error:  # a TPDO late, missing or malformed
                self.log_event(BUS_EVENTS_PATH, str(error))
                raise
            self.after_cycle(result)
        finally:
            self._stepping = False

    def after_cycle(self, result: CycleResult) -> None:
        """What follows every cycle: the SDO poll if due, then the observers."""
        if self._polled is not None:
            self._poll(result.cycle)
        for observer in self.observers:
            observer.on_cycle(result)

    def _wall_now(self) -> float:
        """Real time: the clock now, on rig.t's timeline (time outside run() counts too)."""
        assert isinstance(self.driver, RealTimeDriver)
        return self.driver.now()

    # --- Fields -------------------------------------------------------------------------
    def check_names(self, *names: str) -> None:
        """Fail at once (FieldNameError with close matches) if a name is not in board.toml."""
        self.table.check(names)

    def set(self, name: str, value: float) -> None:
        """Command a bus-writable field: by the RPDO that carries it (sent from the next
        cycle on; the setpoint stream every cycle), otherwise by SDO now. The node judges the
        value; a refused SDO write raises SdoAbortError with the reason in words."""
        self.table.entry(name)
        if self.table.is_hil_input(name):
            raise FieldAccessError(
                f"{name} is a raw sensor input the physics computes every cycle; inject faults "
                "with rig.override_sensors(...)"
            )
        if self.driver.rpdo_of(name) is not None:
            self.driver.set_rpdo_value(name, value)
        else:
            with self._traced_sdo():
                self.node.write(name, value)
            for observer in self.observers:
                observer.on_sdo_write(name, value, cycle=self.cycle, t=self.t)

    def field(self, name: str) -> float | int:
        """Latest value of `name`: from the last TPDO that carried it, else read by SDO."""
        self.table.entry(name)
        if name in self.driver.tpdo_names():
            return self.driver.latest(name)
        return self.read(name)

    def read(self, name: str) -> float | int:
        """The node's present value of `name`, read by SDO."""
        with self._traced_sdo():
            return self.node.read(name)

    @contextmanager
    def _traced_sdo(self) -> Iterator[None]:
        """An SDO abort goes to the observers, then on to the caller; on the timed bus the
        answer (or the abort) reaches the caller once the bus carried it (`_sdo_on_the_bus`)."""
        try:
            yield
        except SdoAbortError as error:
            self._sdo_on_the_bus()
            for observer in self.observers:
                observer.on_sdo_abort(str(error), error.abort_code, cycle=self.cycle, t=self.t)
            raise
        except BaseException:
            timing = getattr(self.driver, "bus_timing", None)
            if timing is not None:
                timing.drop_sdo()
            raise
        self._sdo_on_the_bus()

    def _charge_sdo(self, timing: BusTiming, cob_id: int, dlc: int) -> None:
        """An SDO frame of the master's on the timed bus; not one of the SDO poll inside a cycle
        (`poll_over_sdo`, which nothing waits for: it takes no bus time)."""
        if not self._stepping:
            timing.charge(cob_id, dlc, sdo=True)

    def _sdo_on_the_bus(self) -> None:
        """On the timed bus, between cycles: run cycles until the bus carried the SDO frames
        the rig's transfers sent and read (the master has its answer only then); an
        SdoTimeoutError when none of them got on the bus for SDO_ANSWER_TIMEOUT_S of
        simulation time, as a master's response timeout."""
        timing = getattr(self.driver, "bus_timing", None)
        if timing is None or self._stepping or not timing.sdo_waiting:
            return
        limit = max(1, cycles_for(SDO_ANSWER_TIMEOUT_S, self.period_us))
        quiet = 0
        while timing.sdo_waiting > 0:
            carried = timing.sdo_delivered
            self._step()
            quiet = 0 if timing.sdo_delivered > carried else quiet + 1
            if quiet >= limit:
                timing.drop_sdo()
                assert self.bitrate is not None
                raise SdoTimeoutError(
                    f"node 0x{self.node.node_id:02X}: the bus carried no frame of the SDO transfer "
                    f"for {SDO_ANSWER_TIMEOUT_S:g} s of simulation time (the master's response "
                    f"timeout) at cycle {self.cycle}: {timing.timeline.describe(self.bitrate)}"
                )

    def history(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """(t, values) of `name` for every cycle it was received in a TPDO (or, for what the
        rig sends, every cycle it was sent in an RPDO)."""
        self.table.entry(name)
        history = self.driver.history
        if history.has_received(name):
            return history.received(name)
        if history.has_sent(name):
            return history.sent(name)
        if name in self.driver.tpdo_names() or self.driver.rpdo_of(name) is not None:
            return np.empty(0), np.empty(0)
        raise NoValueError(
            f"{name} is in no enabled PDO, so it has no history: map it, or read "
            "its present value with rig.field()"
        )

    def sent(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """(t, values) of `name` as the rig sent it in RPDOs."""
        self.table.entry(name)
        if not self.driver.history.has_sent(name):
            return np.empty(0), np.empty(0)
        return self.driver.history.sent(name)

    def truth(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """(t, values) of a ground-truth quantity of the plant, e.g. "load_velocity" (or its
        full name "load_velocity_rad_s"), one row per cycle at the cycle's start."""
        self.driver.history.truth_name(name)
        if not self.physics:
            raise NoValueError(f"{name}: the rig runs without physics, so there is no ground truth")
        return self.driver.history.truth(name)

    @property
    def state(self) -> Truth:
        """The plant's present truth (at rig.t)."""
        return self.plant.truth()

    # --- Faults and bus control ---------------------------------------------------------
    def override_sensors(self, override: Callable[[SensorFrame], SensorFrame] | None) -> None:
        """Replace each cycle's sensor frame (`Plant.sense`) before it is sent (None: physics
        only)."""
        self.driver.sensor_override = override

    def pause_rpdo(self, number: int) -> None:
        """Stop sending RPDO `number` (e.g. 2: silence the setpoint stream for the watchdog)."""
        self.driver.paused_rpdos.add(number)

    def resume_rpdo(self, number: int) -> None:
        self.driver.paused_rpdos.discard(number)

    def send_frame(self, cob_id: int, data: bytes) -> None:
        """Send any raw frame on the rig's bus now (floods, malformed frames, rogue masters)."""
        self.driver.send_frame(cob_id, data)

    def nmt(self, command: NmtCommand) -> None:
        """Send an NMT command; after a reset, wait (bounded) for the boot-up. In lockstep the
        node counts its boot time (the table's [node] boot_ms) in control cycles: the rig runs
        exactly those cycles (the node not operational, the plant stepping), then waits for
        the boot-up the last one's SYNC brought, so the cycle after a reset is the same in
        every run."""
        self.node.nmt(command, boot_timeout_s=self.boot_timeout_s, while_booting=self._run_boot)
        self.follow_nmt(command)

    def follow_nmt(self, command: NmtCommand) -> None:
        """The node's NMT state changed by `command` (the rig's, or another master's sent
        between two cycles, whose boot-up after a reset that master waits for): the driver
        expects the TPDOs of that state from the next SYNC, the observers hear of it."""
        self.driver.node_entered(command.resulting_state)
        for observer in self.observers:
            observer.on_nmt(
                command.resulting_state, self.t, cycle=self.cycle, source=f"command {command.name}"
            )

    @property
    def boot_cycles(self) -> int:
        """The cycles a lockstep node's boot after an NMT reset spans (its boot-up comes with
        the last one's SYNC); 0 in real time, where the node boots on the wall clock."""
        if not isinstance(self.driver, LockstepDriver):
            return 0
        return cycles_for(self.table.board.node.boot_ms / 1e3, self.driver.period_us)

    def _run_boot(self) -> None:
        self.driver.node_entered(NmtState.INITIALISING)  # no TPDO until it is started again
        self.run(cycles=self.boot_cycles)

    @property
    def nmt_state(self) -> NmtState | None:
        """State from the node's latest heartbeat (None before any)."""
        return self.node.last_heartbeat

    # --- EMCY ---------------------------------------------------------------------------
    def _on_emcy(self, error: EmcyError) -> None:
        record = EmcyRecord(
            code=error.code,
            register=error.register,
            data=bytes(error.data),
            cycle=self.driver.cycle,
            time_s=self.driver.t,
        )
        with self._emcy_lock:
            self._emcy.append(record)
        for observer in self.observers:
            observer.on_emcy(record)

    def _on_heartbeat_state(self, state: int) -> None:
        """Heartbeat/boot-up state changes to the observers, from canopen's receive thread."""
        try:
            nmt_state = NmtState(state)
        except ValueError:
            return
        if nmt_state is not self._heartbeat_state:
            self._heartbeat_state = nmt_state
            for observer in self.observers:
                observer.on_nmt(nmt_state, self.t, cycle=self.cycle, source="heartbeat")

    @property
    def overruns(self) -> int:
        """Real time: whole ticks the rig missed (0 in lockstep, where time waits for it)."""
        return self.driver.overruns if isinstance(self.driver, RealTimeDriver) else 0

    @property
    def physics_lost_s(self) -> float:
        """Real time: wall seconds the plant skipped because the rig fell behind (0 in lockstep)."""
        return self.driver.physics_lost_s if isinstance(self.driver, RealTimeDriver) else 0.0

    @property
    def emcy(self) -> list[EmcyRecord]:
        """EMCYs received so far, oldest first, with the cycle and time they arrived in."""
        self.driver.poll()  # what arrived since the last cycle
        with self._emcy_lock:
            return list(self._emcy)
