"""The soak's driver: a lean lockstep master on the rig's frame link (`hilrig.wire.transport`: one
raw socket with kernel receive filters for the node's TPDOs, EMCY and heartbeat), with canopen's
SDO client for the SDO a fault needs. Per cycle it sends the sensor and setpoint RPDOs and SYNC,
then checks that every TPDO due at that SYNC arrives once with its mapped length, that the
status TPDO says what the injected faults imply, and that no EMCY goes unexplained; it injects
the planned faults and keeps the tally the firmware's stop line must agree with.
"""

from __future__ import annotations

import math
import struct
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

from canopen.sdo import SdoAbortedError, SdoCommunicationError

from boardproto.cia301 import NMT_COB_ID, SYNC_COB_ID, SYNC_COUNTER_MAX, NmtCommand
from hilrig.apps.soak.fault_plan import FaultPlan, PlannedFault, SoakFault
from hilrig.apps.soak.layout import (
    EMCY_ERROR_RESET,
    EMCY_PDO_LENGTH,
    EMCY_STALE_SENSOR,
    RPDO_COMMUNICATION_BASE,
    STALE_ENCODER_FLAGS,
    SdoObject,
    SensorPattern,
    SoakLayout,
)
from hilrig.apps.soak.memory import DEFAULT_SAMPLE_EVERY, ProcessSample
from hilrig.errors import RigError
from hilrig.wire.transport import FrameLink, can_frame

DEFAULT_MAX_LOST = 10
"""Give up after this many lost cycles (the verdict is already "failed" at the first one)."""
RECEIVE_TIMEOUT_S = 10.0
"""Hang guard per blocking receive (wall clock): far above any cycle time, even in the emulated
VM on a busy host; reaching it means the SYNC went unanswered (a lost cycle)."""
BOOT_TIMEOUT_S = 120.0
"""Start-up of the ASan build inside the emulated VM takes several seconds."""
PROGRESS_EVERY_S = 10.0
REPORT_EVERY_S = 60.0
HOUSEKEEPING_EVERY = 256
"""Cycles between looks at the clock (progress, stop request, partial report)."""

EMCY_PAYLOAD = struct.Struct("<HBH")
"""EMCY: error code, error register, then the board's 'about' object index."""


class SoakError(RigError, RuntimeError):
    """The soak could not go on (the firmware stopped answering, too many lost cycles)."""



@dataclass
class Tally:
    """What the driver put on the bus and got back; the firmware's stop line must agree."""

    syncs_operational: int = 0
    syncs_stopped: int = 0
    frames_sent: int = 0
    """Frames on COB-IDs the node accepts: the firmware's 'frames received'."""
    ignored_expected: int = 0
    frames_filtered: int = 0
    """Frames on COB-IDs outside the node's acceptance filter: on the bus, never received."""
    length_errors: int = 0
    tpdos_received: int = 0
    emcy_received: int = 0
    heartbeats: int = 0

    def expected_counters(self) -> dict[str, int]:
        return {
            "cycles": self.syncs_operational,
            "overruns": 0,
            "frames received": self.frames_sent,
            "ignored": self.ignored_expected,
            "malformed": 0,
            "SDO aborts": 0,
            "RPDO length errors": self.length_errors,
            "TPDOs sent": self.tpdos_received,
            "EMCY": self.emcy_received,
            "send failures": 0,
            "bus error frames": 0,
            "receive overruns": 0,
            "board refused writes": 0,
        }



class SdoPort(Protocol):
    """An SDO client: canopen's `SdoClient` (`RemoteNode.sdo`), or a stand-in in tests. Raises
    canopen's SdoAbortedError / SdoCommunicationError."""

    def upload(self, index: int, subindex: int) -> bytes: ...

    def download(self, index: int, subindex: int, data: bytes) -> None: ...


@dataclass(frozen=True)
class LostCycle:
    cycle: int
    sync_counter: int
    missing: tuple[str, ...]
    received: tuple[str, ...]
    late: tuple[str, ...] = ()


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


Emcy = tuple[int, int]
"""(error code, the object index the board names)."""


class SoakDriver:
    """The lean lockstep master on the rig's frame link (`hilrig.wire.transport`), with canopen's SDO
    client for the SDO it needs. `start()` waits for the node's boot-up and starts it; `run()`
    drives cycles until the count is reached or a stop is requested; `finish()` drains the bus.

    `probe` samples the firmware process (None: no memory figures), `liveness` raises
    FirmwareError once the process died, `stop_requested` is polled every HOUSEKEEPING_EVERY cycles.
    """

    def __init__(
        self,
        link: FrameLink,
        sdo: SdoPort,
        layout: SoakLayout,
        plan: FaultPlan,
        *,
        period_us: int = 1000,
        probe: Callable[[int, float], ProcessSample] | None = None,
        liveness: Callable[[], None] = lambda: None,
        stop_requested: Callable[[], bool] = lambda: False,
        on_progress: Callable[[SoakProgress], None] | None = None,
        on_checkpoint: Callable[[], None] | None = None,
        sample_every: int = DEFAULT_SAMPLE_EVERY,
        max_lost: int = DEFAULT_MAX_LOST,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.layout = layout
        self.plan = plan
        self.pattern = SensorPattern(layout, period_us)
        self.probe = probe
        self.liveness = liveness
        self.stop_requested = stop_requested
        self.on_progress = on_progress
        self.on_checkpoint = on_checkpoint
        self.sample_every = sample_every
        self.max_lost = max_lost
        self.clock = clock
        self._send = link.send
        self._recv = link.recv
        self.sdo = sdo
        self.tally = Tally()
        self.cycle = 0
        """Firmware cycles so far: SYNCs sent while the node was operational."""
        self.cycles_target = 0
        self.lost: list[LostCycle] = []
        self.problems: list[str] = []
        self.problem_count = 0
        self.faults_done: Counter[str] = Counter()
        self.samples: list[ProcessSample] = []
        self.emcy_log: list[tuple[int, int, int]] = []
        """(cycle, code, about) of every EMCY, for the report (a few hundred at most)."""
        self.heartbeat_states: Counter[int] = Counter()
        self.velocity_samples: list[tuple[int, float, float]] = []
        self.started_at: float | None = None
        self.stopped_by_request = False
        self._sync_count = 0
        self._sync_number = 0  # SYNCs since the node entered operational
        self._cycle_emcy: list[Emcy] = []
        self._last_status = b""
        self._velocity_tpdo = next((p for p in layout.tpdos if "motor_velocity" in p.names), None)
        self._velocity_payload = b""
        self._velocity_cob = self._velocity_tpdo.cob_id if self._velocity_tpdo is not None else -1
        self._tpdo_mask = {p.cob_id: 1 << i for i, p in enumerate(layout.tpdos)}
        self._tpdo_length = {p.cob_id: p.length for p in layout.tpdos}
        self._tpdo_by_cob = {p.cob_id: p for p in layout.tpdos}
        period = layout.due_period
        self._due_period = period
        self._due_mask = [
            sum(self._tpdo_mask[p.cob_id] for p in layout.due_at(n if n else period)) for n in range(period)
        ]
        self._healthy_status = layout.status_bytes(0)
        self._latched_status = layout.status_bytes(STALE_ENCODER_FLAGS)
        setpoints = {
            n: self.pattern.output_velocity_rad_s if n == "velocity_setpoint" else 0.0
            for n in layout.setpoint.names
        }
        self._setpoint_frame = can_frame(layout.setpoint.cob_id, layout.setpoint.pack_named(setpoints))
        self._sync_frames = [can_frame(SYNC_COB_ID, bytes([c])) for c in range(1, SYNC_COUNTER_MAX + 1)]
        self.sdo_reads = (
            *layout.sdo_reads,
            SdoObject("control_mode", *layout.control_mode),
            *(
                SdoObject(name, *address, layout.setpoint.object_bytes(name, setpoints[name]))
                for name, address in zip(layout.setpoint.names, layout.setpoint.addresses, strict=True)
            ),
        )
        """What the SDO-upload fault reads: the EDS's fixed objects and what the driver set."""
        self.stale_limit = layout.encoder_stale_cycles
        self._next_sample = 0
        self._next_housekeeping = HOUSEKEEPING_EVERY
        self._next_progress_s = 0.0
        self._next_checkpoint_s = 0.0
        self._last_progress = (0, 0.0)

    # --- Raw frames -----------------------------------------------------------------------
    def _send_counted(self, cob_id: int, data: bytes, *, filtered: bool = False) -> None:
        """`filtered`: a COB-ID outside the node's acceptance filter (the kernel drops it)."""
        self._send(can_frame(cob_id, data))
        if filtered:
            self.tally.frames_filtered += 1
        else:
            self.tally.frames_sent += 1

    def _problem(self, text: str) -> None:
        self.problem_count += 1
        if len(self.problems) < 100:
            self.problems.append(f"cycle {self.cycle}: {text}")

    def _other_frame(self, cob_id: int, data: bytes) -> bool:
        """EMCY or heartbeat between TPDOs; returns False for anything else."""
        if cob_id == self.layout.emcy_cob_id:
            code, _register, about = EMCY_PAYLOAD.unpack_from(data)
            self.tally.emcy_received += 1
            self._cycle_emcy.append((code, about))
            if len(self.emcy_log) < 1000:
                self.emcy_log.append((self.cycle, code, about))
            return True
        if cob_id == self.layout.heartbeat_cob_id:
            self.tally.heartbeats += 1
            self.heartbeat_states[data[0]] += 1
            return True
        return False

    # --- One cycle ------------------------------------------------------------------------
    def _cycle(self, *, sensor: bool = True, status: bytes | None = None, emcy: Sequence[Emcy] = ()) -> None:
        """One lockstep cycle: RPDOs, SYNC, then every TPDO due at it, checked.

        `status` is the status TPDO payload the injected faults imply (default: no fault);
        `emcy` the EMCYs this cycle must bring (default: none)."""
        k = self.cycle + 1
        send = self._send
        if sensor:
            send(self.pattern.frame(k))
        send(self._setpoint_frame)
        send(self._sync_frames[self._sync_count % SYNC_COUNTER_MAX])
        self._sync_count += 1
        self._sync_number += 1
        self.cycle = k
        tally = self.tally
        tally.frames_sent += 3 if sensor else 2
        tally.syncs_operational += 1
        due = self._due_mask[self._sync_number % self._due_period]
        expected_status = self._healthy_status if status is None else status
        bits, lengths, status_cob = self._tpdo_mask, self._tpdo_length, self.layout.status.cob_id
        velocity_cob = self._velocity_cob
        recv = self._recv
        got = 0
        while got != due:
            frame = recv(RECEIVE_TIMEOUT_S)
            if frame is None:
                self._lost_cycle(due, got)
                break
            cob_id, data = frame
            bit = bits.get(cob_id)
            if bit is None:
                if not self._other_frame(cob_id, data):
                    self._problem(f"unexpected frame 0x{cob_id:03X} {data.hex()}")
                continue
            tally.tpdos_received += 1
            if bit & got or not bit & due or len(data) != lengths[cob_id]:
                self._tpdo_problem(cob_id, len(data), bit & got, bit & due)
            got |= bit & due
            if cob_id == status_cob:
                self._last_status = data
                if data != expected_status:
                    self._status_problem(expected_status)
            elif cob_id == velocity_cob:
                self._velocity_payload = data
        if self._cycle_emcy or emcy:
            self._check_emcy(emcy)

    def _tpdo_problem(self, cob_id: int, length: int, twice: int, due: int) -> None:
        pdo = self._tpdo_by_cob[cob_id]
        if twice:
            self._problem(f"{pdo.label} arrived twice after one SYNC")
        elif not due:
            self._problem(f"{pdo.label} arrived but is not due at SYNC {self._sync_number} since operational")
        else:
            self._problem(f"{pdo.label} has {length} bytes, its mapping {pdo.length}")

    def _status_problem(self, expected: bytes) -> None:
        codec = self.layout.status.codec
        names = self.layout.status.names
        got = dict(zip(names, codec.unpack(self._last_status[: codec.size]), strict=True))
        want = dict(zip(names, codec.unpack(expected), strict=True))
        self._problem(f"{self.layout.status.label}: expected {want}, got {got}")

    def _check_emcy(self, expected: Sequence[Emcy]) -> None:
        got, self._cycle_emcy = self._cycle_emcy, []
        if sorted(got) != sorted(expected):
            words = ", ".join(f"0x{code:04X} about 0x{about:04X}" for code, about in got) or "none"
            wanted = ", ".join(f"0x{code:04X} about 0x{about:04X}" for code, about in expected) or "none"
            self._problem(f"EMCY: expected {wanted}, got {words}")

    def _lost_cycle(self, due: int, got: int) -> None:
        labels = {p.cob_id: p.label for p in self.layout.tpdos}
        missing = tuple(labels[c] for c, b in self._tpdo_mask.items() if due & b and not got & b)
        received = tuple(labels[c] for c, b in self._tpdo_mask.items() if got & b)
        self.liveness()  # a dead firmware reads as a crash, not as a lost cycle
        late = self._barrier(late_ok=True)
        self.lost.append(
            LostCycle(self.cycle, (self._sync_count - 1) % SYNC_COUNTER_MAX + 1, missing, received, late)
        )
        self._problem(
            f"lost: {', '.join(missing)} did not arrive within {RECEIVE_TIMEOUT_S:g} s"
            + (f" (late: {', '.join(late)})" if late else "")
        )
        if len(self.lost) > self.max_lost:
            raise SoakError(
                f"{len(self.lost)} lost cycles (limit {self.max_lost}); last at cycle {self.cycle}"
            )

    # --- SDO ------------------------------------------------------------------------------
    def _sdo(
        self,
        what: str,
        transfer: Callable[[], bytes | None],
        *,
        late_ok: bool = False,
        late: list[str] | None = None,
    ) -> tuple[bool, bytes | None]:
        """One SDO transfer through canopen (one request frame: every object here is expedited),
        then whatever the node sent before its answer: the answer comes after it, so it is in
        the link's queue by now. EMCY and heartbeat are kept, a TPDO is a problem (between SYNCs
        nothing is due) unless `late_ok` (resynchronising after a lost cycle: it is late).
        Returns (whether it succeeded, what the transfer returned); a failure is a problem."""
        self.tally.frames_sent += 1
        try:
            result = transfer()
            ok = True
        except SdoAbortedError as error:
            self._problem(f"{what}: abort 0x{error.code:08X}")
            result, ok = None, False
        except SdoCommunicationError as error:
            self.liveness()
            self._problem(f"{what}: no SDO answer within {RECEIVE_TIMEOUT_S:g} s ({error})")
            result, ok = None, False
        while (frame := self._recv(0.0)) is not None:
            cob_id, data = frame
            if cob_id in self._tpdo_mask:
                self.tally.tpdos_received += 1
                label = self._tpdo_by_cob[cob_id].label
                if late_ok and late is not None:
                    late.append(label)
                else:
                    self._problem(f"{label} arrived between SYNCs (no SYNC was due an answer)")
            elif not self._other_frame(cob_id, data):
                self._problem(f"unexpected frame 0x{cob_id:03X} while waiting for an SDO answer")
        return ok, result

    def sdo_upload(self, obj: SdoObject, *, late_ok: bool = False, late: list[str] | None = None) -> bool:
        """Read `obj` and check the answer; False (and a problem) when it is wrong."""
        what = f"SDO upload {obj.label}"
        ok, answer = self._sdo(
            what, lambda: self.sdo.upload(obj.index, obj.subindex), late_ok=late_ok, late=late
        )
        if ok and answer != obj.expected:
            self._problem(
                f"{what} 0x{obj.index:04X}:{obj.subindex}: expected {obj.expected.hex()}, got "
                f"{(answer or b'').hex()}"
            )
            return False
        return ok

    def sdo_download(self, label: str, index: int, subindex: int, data: bytes) -> bool:
        ok, _ = self._sdo(f"SDO download {label}", lambda: self.sdo.download(index, subindex, data))
        return ok

    def _barrier(self, *, late_ok: bool = False) -> tuple[str, ...]:
        """An SDO round trip: the node answers in order, so whatever it sent before is in."""
        late: list[str] = []
        self.sdo_upload(self.layout.sdo_reads[0], late_ok=late_ok, late=late)
        return tuple(late)

    # --- Start, run, finish -----------------------------------------------------------------
    def start(self, boot_timeout_s: float = BOOT_TIMEOUT_S) -> None:
        """Wait for the boot-up, put the node in velocity mode, check the stale limit, start it."""
        deadline = self.clock() + boot_timeout_s
        while True:  # the boot-up, or (when it went out before the link was open) a heartbeat
            frame = self._recv(1.0)
            if frame is None:
                self.liveness()
                if self.clock() > deadline:
                    raise SoakError(
                        f"no boot-up or heartbeat from node 0x{self.layout.node_id:02X} within "
                        f"{boot_timeout_s} s"
                    )
                continue
            if frame[0] == self.layout.heartbeat_cob_id:
                break
        stale = next(o for o in self.layout.sdo_reads if o.label == "encoder_stale_cycles")
        if not self.sdo_upload(stale):
            raise SoakError("the node's encoder_stale_cycles is not the EDS default: " + self.problems[-1])
        if not self.sdo_download("control_mode", *self.layout.control_mode):
            raise SoakError("cannot put the node in velocity mode: " + self.problems[-1])
        self._nmt(NmtCommand.START)
        self.started_at = self.clock()
        self._next_progress_s = self.started_at + PROGRESS_EVERY_S
        self._next_checkpoint_s = self.started_at + REPORT_EVERY_S
        self._last_progress = (0, self.started_at)

    def _nmt(self, command: NmtCommand) -> None:
        self._send_counted(NMT_COB_ID, bytes([int(command), self.layout.node_id]))
        if command is NmtCommand.START:
            self._sync_number = 0  # the node counts SYNCs for its TPDOs from here

    def run(self, cycles: int) -> None:
        """Drive cycles until `cycles` firmware cycles ran or a stop was requested."""
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
        if self._cycle_emcy:
            self._check_emcy(())
        if not self.samples or self.samples[-1].cycle != self.cycle:
            self._sample(force=True)

    def _sample(self, *, force: bool = False) -> None:
        self._next_sample = (self.cycle // self.sample_every + 1) * self.sample_every
        if self._velocity_tpdo is not None:
            self._record_velocity()
        if self.probe is None:
            return
        elapsed = self.clock() - (self.started_at or self.clock())
        sample = self.probe(self.cycle, elapsed)
        if force or not self.samples or self.samples[-1].cycle != sample.cycle:
            self.samples.append(sample)

    def _record_velocity(self) -> None:
        """Decode the latest motor and output velocity (once per sample): a content check of a
        TPDO that is otherwise only counted, and a window on how the estimate ages."""
        pdo = self._velocity_tpdo
        if pdo is None or not self._velocity_payload:
            return
        values = dict(zip(pdo.names, pdo.codec.unpack_from(self._velocity_payload), strict=True))
        self.velocity_samples.append(
            (self.cycle, values["motor_velocity"], values.get("output_velocity", math.nan))
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
            lost=len(self.lost),
            problems=self.problem_count,
        )

    # --- Faults ---------------------------------------------------------------------------
    def _malformed_rpdo(self, fault: PlannedFault) -> None:
        """A sensor RPDO shorter than its mapping: refused (EMCY 0x8210 naming 0x1400+n), and the
        good frame right after ends the error (EMCY error reset); the cycle runs normally."""
        sensor = self.layout.sensor
        self._send_counted(sensor.cob_id, bytes((fault.cycle + i) & 0xFF for i in range(fault.arg)))
        self.tally.length_errors += 1
        about = RPDO_COMMUNICATION_BASE + sensor.number - 1
        self._cycle(emcy=((EMCY_PDO_LENGTH, about), (EMCY_ERROR_RESET, 0)))

    def _unknown_cob_id(self, fault: PlannedFault) -> None:
        """A frame on a COB-ID this node does not use: its acceptance filter drops it (neither
        received nor ignored in the stop line), no answer, the cycle runs normally."""
        length = fault.cycle % 9
        self._send_counted(
            fault.arg, bytes((fault.cycle * 7 + i) & 0xFF for i in range(length)), filtered=True
        )
        self._cycle()

    def _sdo_upload_fault(self, fault: PlannedFault) -> None:
        """An SDO upload between two cycles, answered with the right value."""
        self.sdo_upload(self.sdo_reads[fault.arg % len(self.sdo_reads)])
        self._cycle()

    def _stale_sensor(self, fault: PlannedFault) -> None:
        """Withhold the sensor RPDO: both encoder-stale bits latch exactly at the
        encoder_stale_cycles-th silent cycle (EMCY 0x5000 naming each position), stay latched
        after the sensor is back, and clear in the first cycle after fault_clear = 1 (error resets)."""
        limit = self.stale_limit
        latched = self._latched_status
        stale_emcy = tuple((EMCY_STALE_SENSOR, about) for about in self.layout.stale_about)
        for silent in range(1, limit + fault.arg + 1):
            if silent < limit:
                self._cycle(sensor=False)
            else:
                self._cycle(sensor=False, status=latched, emcy=stale_emcy if silent == limit else ())
        for _ in range(2):
            self._cycle(status=latched)  # the cause is gone, the latch holds
        self.sdo_download("fault_clear", *self.layout.fault_clear)
        self._cycle(emcy=tuple((EMCY_ERROR_RESET, 0) for _ in self.layout.stale_about))

    def _nmt_stop_start(self, fault: PlannedFault) -> None:
        """NMT stop, then `arg` cycles' worth of RPDOs and SYNC the node must ignore (no cycle, no
        TPDO), NMT start, and an SDO round trip as the barrier: any TPDO before its answer was
        sent while stopped."""
        self._nmt(NmtCommand.STOP)
        for _ in range(fault.arg):
            self._send(self.pattern.frame(self.cycle + 1))
            self._send(self._setpoint_frame)
            self._send(self._sync_frames[self._sync_count % SYNC_COUNTER_MAX])
            self._sync_count += 1
            self.tally.frames_sent += 3
            self.tally.ignored_expected += 3
            self.tally.syncs_stopped += 1
        self._nmt(NmtCommand.START)
        self._barrier()
        self._cycle()

