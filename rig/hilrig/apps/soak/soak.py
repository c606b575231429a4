"""The soak as a program on the engine: the engine's lockstep driver (`hilrig.engine.lockstep`)
runs every cycle (the sensor and setpoint RPDOs, SYNC, the TPDOs due at it, the hang guard),
with the sensor pattern as its plant and a history that keeps nothing; `Soak` injects the planned
faults between cycles, has the checker judge each cycle (`checker.CycleChecker`), samples the
firmware's memory and reports progress. NMT and SDO go through the node (`hilrig.wire.node`).
"""

from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from boardproto.cia301 import EMCY_ERROR_RESET, NmtCommand
from hilrig.apps.soak.checker import DEFAULT_MAX_LOST, CycleChecker, Emcy, SoakError
from hilrig.apps.soak.fault_plan import FaultPlan, PlannedFault, SoakFault
from hilrig.apps.soak.layout import (
    EMCY_PDO_LENGTH,
    EMCY_STALE_SENSOR,
    RPDO_COMMUNICATION_BASE,
    SdoObject,
    SensorPattern,
    SoakLayout,
)
from hilrig.apps.soak.memory import DEFAULT_SAMPLE_EVERY, ProcessSample
from hilrig.engine.driver import ProcessActivity
from hilrig.engine.lockstep import LockstepDriver
from hilrig.errors import SdoAbortError, SdoTimeoutError
from hilrig.table import BOARD_TABLE
from hilrig.wire.node import BoardNode
from hilrig.wire.transport import PdoLayout, Value

RECEIVE_TIMEOUT_S = 10.0
"""The hang guard's timeout (`hilrig.engine.lockstep.HangGuard`) and the SDO answer's: far above
any cycle time, even in the emulated VM on a busy host; a cycle the guard gives up on is lost."""
BOOT_TIMEOUT_S = 120.0
"""Start-up of the ASan build inside the emulated VM takes several seconds."""
PROGRESS_EVERY_S = 10.0
REPORT_EVERY_S = 60.0
HOUSEKEEPING_EVERY = 256
"""Cycles between looks at the clock (progress, stop request, partial report)."""


@dataclass
class SoakProgress:
    cycle: int
    cycles: int
    elapsed_s: float
    rate: float
    recent_rate: float
    sample: ProcessSample | None
    faults: int
    lost: int
    problems: int


class Soak:
    """The soak's run over the engine's lockstep driver on `node`. `start()` waits for the node's
    heartbeat and starts it; `run()` runs cycles until the count is reached or a stop is
    requested, with the planned faults between them; `finish()` drains the bus.

    `probe` samples the firmware process (None: no memory figures), `liveness` raises
    FirmwareError once the process died, `activity` is its CPU time and sleep state (the hang
    guard tells a busy host from a stuck firmware with it), `stop_requested` is polled every
    HOUSEKEEPING_EVERY cycles.
    """

    def __init__(
        self,
        node: BoardNode,
        layout: SoakLayout,
        plan: FaultPlan,
        *,
        period_us: int = BOARD_TABLE.node.period_us,
        probe: Callable[[int, float], ProcessSample] | None = None,
        liveness: Callable[[], None] = lambda: None,
        activity: Callable[[], ProcessActivity | None] | None = None,
        stop_requested: Callable[[], bool] = lambda: False,
        on_progress: Callable[[SoakProgress], None] | None = None,
        on_checkpoint: Callable[[], None] | None = None,
        sample_every: int = DEFAULT_SAMPLE_EVERY,
        max_lost: int = DEFAULT_MAX_LOST,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.node = node
        self.layout = layout
        self.plan = plan
        self.pattern = SensorPattern(layout, period_us)
        self.checker = CycleChecker(layout, max_lost=max_lost)
        self.driver = LockstepDriver(
            node,
            self.pattern,
            period_us=period_us,
            tpdo_timeout_s=RECEIVE_TIMEOUT_S,
            liveness=liveness,
            activity=activity,
            keep_history=False,
        )
        self.driver.on_problem = self.checker.on_problem
        self.driver.listen(layout.emcy_cob_id, self.checker.on_emcy)
        self.driver.listen(layout.heartbeat_cob_id, self.checker.on_heartbeat)
        self.probe = probe
        self.liveness = liveness
        self.stop_requested = stop_requested
        self.on_progress = on_progress
        self.on_checkpoint = on_checkpoint
        self.sample_every = sample_every
        self.clock = clock
        self.cycle = 0
        """Firmware cycles so far: SYNCs sent while the node was operational."""
        self.cycles_target = 0
        self.faults_done: Counter[str] = Counter()
        self.samples: list[ProcessSample] = []
        self.velocity_samples: list[tuple[int, float, float]] = []
        self.started_at: float | None = None
        self.stopped_by_request = False
        self.setpoints: dict[str, Value] = {
            name: self.pattern.output_velocity_rad_s if name == "velocity_setpoint" else 0.0
            for name in layout.setpoint.names
        }
        """What the setpoint stream carries (the output speed of the sensor pattern)."""
        self.sdo_reads = (
            *layout.sdo_reads,
            SdoObject("control_mode", *layout.control_mode),
            *(
                SdoObject(name, *address, layout.setpoint.object_bytes(name, self.setpoints[name]))
                for name, address in zip(layout.setpoint.names, layout.setpoint.addresses, strict=True)
            ),
        )
        """What the SDO-upload fault reads: the EDS's fixed objects and what the soak set."""
        self._next_sample = 0
        self._next_housekeeping = HOUSEKEEPING_EVERY
        self._next_progress_s = 0.0
        self._next_checkpoint_s = 0.0
        self._last_progress = (0, 0.0)

    # --- Start, run, finish -----------------------------------------------------------------
    def start(self, boot_timeout_s: float = BOOT_TIMEOUT_S) -> None:
        """Configure the driver from the EDS's PDO mapping (as the layout; no SDO traffic, which
        the firmware would count), wait for the node's heartbeat, put it in velocity mode,
        check the stale limit, start it."""
        self.node.read_pdo_configuration(from_node=False)
        driver = self.driver
        driver.configure()
        for name, value in self.setpoints.items():
            driver.set_rpdo_value(name, value)
        deadline = self.clock() + boot_timeout_s
        while not self.checker.tally.heartbeats:  # the boot-up may have gone out before the link was open
            driver.poll(1.0)
            if self.checker.tally.heartbeats:
                break
            self.liveness()
            if self.clock() > deadline:
                raise SoakError(
                    f"no heartbeat from node 0x{self.layout.node_id:02X} within {boot_timeout_s} s"
                )
        stale = next(o for o in self.layout.sdo_reads if o.label == "encoder_stale_cycles")
        if not self.sdo_upload(stale):
            problem = self.checker.problems[-1]
            raise SoakError(f"the node's encoder_stale_cycles is not the EDS default: {problem}")
        if not self.sdo_download("control_mode", *self.layout.control_mode):
            raise SoakError("cannot put the node in velocity mode: " + self.checker.problems[-1])
        self._nmt(NmtCommand.START)
        self.started_at = self.clock()
        self._next_progress_s = self.started_at + PROGRESS_EVERY_S
        self._next_checkpoint_s = self.started_at + REPORT_EVERY_S
        self._last_progress = (0, self.started_at)

    def run(self, cycles: int) -> None:
        """Run cycles until `cycles` firmware cycles ran or a stop was requested."""
        self.cycles_target = cycles
        if not self.samples:
            self._sample(force=True)
        faults = iter(self.plan.faults)
        next_fault = next(faults, None)
        inject = {
            SoakFault.MALFORMED_RPDO: self._malformed_rpdo,
            SoakFault.UNKNOWN_COB_ID: self._unknown_cob_id,
            SoakFault.SDO_UPLOAD: self._sdo_upload_fault,
            SoakFault.STALE_SENSOR: self._stale_sensor,
            SoakFault.NMT_STOP_START: self._nmt_stop_start,
        }
        cycle = self._cycle
        while self.cycle < cycles:
            if next_fault is not None and self.cycle + 1 >= next_fault.cycle:
                inject[next_fault.kind](next_fault)
                self.faults_done[next_fault.kind.value] += 1
                next_fault = next(faults, None)
            else:
                cycle()
            if self.cycle >= self._next_sample:
                self._sample()
            if self.cycle >= self._next_housekeeping:
                self._next_housekeeping = self.cycle + HOUSEKEEPING_EVERY
                if self._housekeeping():
                    self.stopped_by_request = True
                    break

    def finish(self) -> None:
        """Drain: an SDO round trip proves nothing more is on its way; sample memory once more."""
        self._barrier()
        if self.checker.emcy_pending:
            self.checker.check_emcy(())
        if not self.samples or self.samples[-1].cycle != self.cycle:
            self._sample(force=True)

    # --- Cycles -------------------------------------------------------------------------
    def _cycle(self, *, status: tuple[Value, ...] | None = None, emcy: Sequence[Emcy] = ()) -> None:
        """One firmware cycle through the engine's driver, checked: `status` is the status
        TPDO's values the injected faults imply (default: no fault), `emcy` the EMCYs this
        cycle must bring (default: none)."""
        k = self.cycle + 1
        self.cycle = self.checker.cycle = self.pattern.cycle = k
        result = self.driver.step()
        checker = self.checker
        checker.operational_cycle(result, status, emcy)
        lost = checker.lost_problem
        if lost is not None:
            # The node answers in order: after an SDO round trip whatever it still sent is in.
            late: list[PdoLayout] = []
            self.sdo_upload(self.layout.sdo_reads[0], late=late)
            checker.lost_cycle(lost, result.sync_counter, late)

    def _nmt(self, command: NmtCommand) -> None:
        self.node.nmt(command)
        self.driver.node_entered(command.resulting_state)  # the node counts SYNCs from here
        self.checker.tally.frames_sent += 1

    # --- SDO ------------------------------------------------------------------------------
    def _sdo(
        self, what: str, transfer: Callable[[], bytes | None], late: list[PdoLayout] | None
    ) -> tuple[bool, bytes | None]:
        """One SDO transfer through the node (one request frame: every object here is
        expedited), then whatever the node sent before its answer: the answer comes after it,
        so it is in the link's queue by now. EMCY and heartbeat go to the checker, a TPDO is a
        problem (between SYNCs nothing is due) unless `late` takes it (resynchronising after a
        lost cycle). Returns (whether it succeeded, what the transfer returned); a failure is a
        problem."""
        checker = self.checker
        checker.tally.frames_sent += 1
        ok, result = False, None
        try:
            result, ok = transfer(), True
        except SdoAbortError as error:
            checker.problem(str(error))
        except SdoTimeoutError as error:
            self.liveness()
            checker.problem(str(error))
        for pdo, _data in self.driver.take_late_tpdos():
            if late is not None:
                late.append(pdo)
            else:
                checker.tally.tpdos_received += 1
                checker.problem(f"{pdo.label} arrived between SYNCs (no SYNC was due an answer)")
        return ok, result

    def sdo_upload(self, obj: SdoObject, *, late: list[PdoLayout] | None = None) -> bool:
        """Read `obj` and check the answer; False (and a problem) when it is wrong."""
        what = f"SDO upload {obj.label}"
        ok, answer = self._sdo(what, lambda: self.node.upload(obj.index, obj.subindex, what), late)
        if ok and answer != obj.expected:
            self.checker.problem(
                f"{what} 0x{obj.index:04X}:{obj.subindex}: expected {obj.expected.hex()}, got "
                f"{(answer or b'').hex()}"
            )
            return False
        return ok

    def sdo_download(self, label: str, index: int, subindex: int, data: bytes) -> bool:
        what = f"SDO download {label}"
        ok, _ = self._sdo(what, lambda: self.node.download(index, subindex, data, what), None)
        return ok

    def _barrier(self) -> None:
        """An SDO round trip: the node answers in order, so whatever it sent before is in."""
        self.sdo_upload(self.layout.sdo_reads[0])

    # --- Memory, progress -----------------------------------------------------------------
    def _sample(self, *, force: bool = False) -> None:
        self._next_sample = (self.cycle // self.sample_every + 1) * self.sample_every
        self._record_velocity()
        if self.probe is None:
            return
        elapsed = self.clock() - (self.started_at or self.clock())
        sample = self.probe(self.cycle, elapsed)
        if force or not self.samples or self.samples[-1].cycle != sample.cycle:
            self.samples.append(sample)

    def _record_velocity(self) -> None:
        """The latest motor and output velocity (once per sample): a content check of a TPDO
        that is otherwise only counted, and a window on how the estimate ages."""
        pdo, values = self.checker.velocity_tpdo, self.checker.velocity
        if pdo is None or values is None:
            return
        named = dict(zip(pdo.names, values, strict=True))
        self.velocity_samples.append(
            (self.cycle, float(named["motor_velocity"]), float(named.get("output_velocity", math.nan)))
        )

    def _housekeeping(self) -> bool:
        """Progress, checkpoint, stop request; True to stop."""
        now = self.clock()
        if self.on_progress is not None and now >= self._next_progress_s:
            self._next_progress_s = now + PROGRESS_EVERY_S
            self.on_progress(self.progress(now))
        if self.on_checkpoint is not None and now >= self._next_checkpoint_s:
            self._next_checkpoint_s = now + REPORT_EVERY_S
            self.on_checkpoint()
        return self.stop_requested()

    def progress(self, now: float | None = None) -> SoakProgress:
        now = self.clock() if now is None else now
        started = self.started_at if self.started_at is not None else now
        elapsed = now - started
        last_cycle, last_time = self._last_progress
        recent = (self.cycle - last_cycle) / (now - last_time) if now > last_time else 0.0
        self._last_progress = (self.cycle, now)
        return SoakProgress(
            cycle=self.cycle,
            cycles=self.cycles_target,
            elapsed_s=elapsed,
            rate=self.cycle / elapsed if elapsed > 0 else 0.0,
            recent_rate=recent,
            sample=self.samples[-1] if self.samples else None,
            faults=sum(self.faults_done.values()),
            lost=len(self.checker.lost),
            problems=self.checker.problem_count,
        )

    # --- Faults ---------------------------------------------------------------------------
    def _malformed_rpdo(self, fault: PlannedFault) -> None:
        """A sensor RPDO shorter than its mapping: refused (EMCY 0x8210 naming 0x1400+n), and the
        good frame right after ends the error (EMCY error reset); the cycle runs normally."""
        sensor = self.layout.sensor
        self.driver.send_frame(sensor.cob_id, bytes((fault.cycle + i) & 0xFF for i in range(fault.arg)))
        self.checker.tally.frames_sent += 1
        self.checker.tally.length_errors += 1
        about = RPDO_COMMUNICATION_BASE + sensor.number - 1
        self._cycle(emcy=((EMCY_PDO_LENGTH, about), (EMCY_ERROR_RESET, 0)))

    def _unknown_cob_id(self, fault: PlannedFault) -> None:
        """A frame on a COB-ID this node does not use: its acceptance filter drops it (neither
        received nor ignored in the stop line), no answer, the cycle runs normally."""
        length = fault.cycle % 9
        self.driver.send_frame(fault.arg, bytes((fault.cycle * 7 + i) & 0xFF for i in range(length)))
        self.checker.tally.frames_filtered += 1
        self._cycle()

    def _sdo_upload_fault(self, fault: PlannedFault) -> None:
        """An SDO upload between two cycles, answered with the right value."""
        self.sdo_upload(self.sdo_reads[fault.arg % len(self.sdo_reads)])
        self._cycle()

    def _stale_sensor(self, fault: PlannedFault) -> None:
        """Withhold the sensor RPDO: both encoder-stale bits latch exactly at the
        encoder_stale_cycles-th silent cycle (EMCY 0x5000 naming each position), stay latched
        after the sensor is back, and clear in the first cycle after fault_clear = 1 (error resets)."""
        limit = self.layout.encoder_stale_cycles
        latched = self.checker.latched_status
        stale_emcy = tuple((EMCY_STALE_SENSOR, about) for about in self.layout.stale_about)
        paused = self.driver.paused_rpdos
        paused.add(self.layout.sensor.number)
        for silent in range(1, limit + fault.arg + 1):
            if silent < limit:
                self._cycle()
            else:
                self._cycle(status=latched, emcy=stale_emcy if silent == limit else ())
        paused.discard(self.layout.sensor.number)
        for _ in range(2):
            self._cycle(status=latched)  # the cause is gone, the latch holds
        self.sdo_download("fault_clear", *self.layout.fault_clear)
        self._cycle(emcy=tuple((EMCY_ERROR_RESET, 0) for _ in self.layout.stale_about))

    def _nmt_stop_start(self, fault: PlannedFault) -> None:
        """NMT stop, then `arg` cycles' worth of RPDOs and SYNC the node must ignore (no cycle, no
        TPDO), NMT start, and an SDO round trip as the barrier: any TPDO before its answer was
        sent while stopped."""
        self._nmt(NmtCommand.STOP)
        self.pattern.cycle = self.cycle + 1
        for _ in range(fault.arg):
            self.checker.stopped_cycle(self.driver.step())
        self._nmt(NmtCommand.START)
        self._barrier()
        self._cycle()
