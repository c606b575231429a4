"""The lockstep driver: the rig is the SYNC producer and each SYNC is one control cycle.

One cycle (index n, simulation time t = n * period, exact):

1. sample the plant (`hilrig.plants.interface.Plant`): its sensor frame -> the RPDO(s) mapping
   the HIL inputs, and its truth;
2. send the setpoint stream (the RPDOs carrying the table's `stream = true` fields, every cycle
   like a real master; a firmware's watchdog may watch it) and any other RPDO a scenario changed;
3. send SYNC with counter (n mod 240) + 1;
4. wait for every synchronous TPDO due at this SYNC (type k: every k-th SYNC since the node
   entered operational); the wall-clock bound is only a hang guard (`HangGuard`), and one that
   a busy host does not trip where the firmware process can be watched;
5. apply the plant's actuator fields from the TPDOs that carry them, step it by one period.

Every cycle's received values, sent values and the plant's ground truth go into `History`.

A TPDO the rules refuse (twice, not due, between SYNCs, the wrong length) or one the hang guard
gave up on ends the cycle with a LockstepError: a scenario's verdict. A program that judges each
cycle and goes on (the soak) sets `on_problem` instead: it gets each problem (`CycleProblem`),
the refused frame is dropped, and a cycle whose due TPDOs did not all come ends without them.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass

from hilrig.engine.bustiming import BusTiming
from hilrig.engine.driver import (
    LIVENESS_SLICE_S,
    SYNC_FRAMES,
    CycleResult,
    Driver,
    History,
    PdoRow,
    ProcessActivity,
    SensorFrame,
    Truth,
    Value,
    resolve_truth_name,
    sync_counter,
)
from hilrig.errors import FirmwareError, HostStarvedError, LockstepError
from hilrig.wire.bustime import TimedBus
from hilrig.wire.transport import (
    ARRIVAL,
    CAN_HEADER_SIZE,
    Decoder,
    PdoLayout,
    append_frame_rows,
    append_row,
    send_frames,
)

_NOTHING_DUE: frozenset[int] = frozenset()


HANG_CAP_FACTOR = 24
"""With the firmware process watched, no wait lasts longer than this many TPDO timeouts of wall
time (2 min at the default 5 s), whatever the host: a host starved that long ends the scenario,
and says so (`HostStarvedError`)."""
IDLE_CPU_SHARE = 0.1
"""A slice of a wait counts as idle when the firmware was asleep at its end and used less than
this share of the slice in CPU: a node that will answer is either runnable or working."""


class HangGuard:
    """When one wait for a cycle's due TPDOs gives up. Made at the wait's first quiet slice (a
    cycle that answers in time never reads /proc), then `check` after each further one.

    Without a view of the node's process (a real board, a fake node): after `timeout_s` of
    waiting, as every hang guard. With one (`activity`: the firmware's `ProcessActivity`), a
    busy host must not read as a broken firmware, so waiting counts only while the firmware
    could have answered and did not:

    - asleep with next to no CPU for `timeout_s` in a row: what it waits for will not come (a
      frame lost, a rule that keeps it silent);
    - `timeout_s` of CPU used without an answer: a loop that does not end;
    - otherwise the host is slow (the firmware runnable, getting little CPU: another VM, a
      mutation run, a shared CI runner) and the wait goes on, up to HANG_CAP_FACTOR timeouts;
      ending there is a `HostStarvedError`, which names the host, not the firmware.
    """

    def __init__(
        self, timeout_s: float, activity: Callable[[], ProcessActivity | None] | None, first_slice_s: float
    ) -> None:
        self.timeout_s = timeout_s
        self.activity = activity
        self.waited_s = first_slice_s
        self._idle_s = 0.0
        self._start = self._last = activity() if activity is not None else None

    def check(self, slice_s: float) -> str | None:
        """One more quiet slice of `slice_s` passed: None to wait on, else why the wait ends,
        said after "TPDOn did not arrive"; HostStarvedError when only the host is to blame."""
        self.waited_s += slice_s
        now = self.activity() if self.activity is not None else None
        if now is None or self._start is None or self._last is None:
            return f" within {self.timeout_s:g} s" if self.waited_s >= self.timeout_s else None
        used = now.cpu_s - self._last.cpu_s
        self._last = now
        quiet = now.sleeping and used < IDLE_CPU_SHARE * slice_s
        self._idle_s = self._idle_s + slice_s if quiet else 0.0
        if self._idle_s >= self.timeout_s:
            return (
                f": the firmware sat idle for {self._idle_s:g} s with them due "
                f"({self.waited_s:g} s waited in all)"
            )
        spent = now.cpu_s - self._start.cpu_s
        if spent >= self.timeout_s:
            return (
                f": the firmware used {spent:.3g} s of CPU in {self.waited_s:g} s without "
                "answering (a loop that does not end?)"
            )
        if self.waited_s >= HANG_CAP_FACTOR * self.timeout_s:
            raise HostStarvedError(
                f"the host is starved, not a firmware verdict: no answer in {self.waited_s:g} s "
                f"of wall time, while the firmware, neither idle nor spinning, got {spent:.3g} s of CPU"
            )
        return None


@dataclass(frozen=True, slots=True)
class CycleProblem:
    """What `LockstepDriver.on_problem` gets instead of a LockstepError: a frame of cycle `cycle`
    the rules refuse (`refused`: the TPDO it came on; the frame is dropped), or due TPDOs the
    hang guard gave up on (`missing`; the cycle ended without them)."""

    cycle: int
    t: float
    what: str
    """What went wrong, as the LockstepError would say it after "cycle n (t = ...): "."""
    refused: PdoLayout | None = None
    missing: tuple[PdoLayout, ...] = ()
    received: tuple[PdoLayout, ...] = ()
    """With `missing`: the due TPDOs that did arrive."""

    def error(self) -> LockstepError:
        return LockstepError(f"cycle {self.cycle} (t = {self.t:.6g} s): {self.what}")


@dataclass(slots=True)
class CycleStart:
    """What the first phase of a lockstep cycle did: the sensor frame it sampled from `state`,
    the RPDOs it sent, and the TPDOs (COB-IDs) due at its SYNC."""

    cycle: int
    t: float
    counter: int
    raw: SensorFrame
    state: Truth
    due: frozenset[int]
    sync_number: int
    sent: tuple[PdoRow, ...]
    frames: bytes
    """The frames of `sent`, joined (the history files their payloads: `end_cycle`)."""
    unsent: bytes = b""
    """`frames` when `begin_cycle(send=False)` left them to go out with the SYNC in the cycle's
    exchange (`step`)."""


class LockstepDriver(Driver):
    """Runs lockstep cycles between a `BoardNode` and the joint plant.

    Single-threaded: the cycle sends its frames and then reads the node's answers itself from
    the frame link (a raw socket with kernel filters on SocketCAN), decoding them with the codecs
    compiled from the node's PDO configuration; no receive thread, no hand-over per frame. On a
    raw socket a cycle's RPDOs and SYNC go out, and its due TPDOs come in decoded, in one call
    each (`transport.exchange`); any other frame comes back to `_collect`'s rules at once.
    """

    on_problem: Callable[[CycleProblem], None] | None = None
    """None: a problem of a cycle raises LockstepError. Set: it gets each problem and the cycle
    goes on (see the module's docstring)."""

    bus_timing: BusTiming | None = None
    """The bus's bit rate (`hilrig.engine.bustiming`): None, the ideal bus (every frame in its
    cycle). Set with `time_bus`."""

    def time_bus(self, bus: TimedBus | None, heartbeat_every: int = 0) -> None:
        """Run the next cycles on `bus` (None: the ideal bus again); after configure(), whose
        TPDOs it times. `heartbeat_every`: the node's heartbeat producer time in cycles."""
        before = self.bus_timing
        self.bus_timing = (
            None
            if bus is None
            else BusTiming(bus, self._tpdo_by_cob, self.node.node_id, heartbeat_every, self.cycle)
        )
        if before is not None and self.bus_timing is not None:  # a reconfigured node: one timeline
            self.bus_timing.timeline = before.timeline
        self.history.bus_timeline = None if self.bus_timing is None else self.bus_timing.timeline

    def _other_frame(self, cob_id: int, data: bytes) -> None:
        """An EMCY takes the timed bus's time too (`BusTiming.charge`), then goes on as ever."""
        timing = self.bus_timing
        if timing is not None and cob_id == self._emcy_cob_id:
            timing.charge(cob_id, len(data))
        super()._other_frame(cob_id, data)

    def step(self) -> CycleResult:
        n, state, raw, due, sync_number, sent, frames = self._sample()
        t, counter = self.history.time_of(n), sync_counter(n)
        timing = self.bus_timing
        if timing is not None:
            sent, frames = timing.plan(n, due, sent, frames)
        # The RPDOs, then the SYNC, in the exchange's one call (`_collect`); the TPDOs' delays
        # after it are their arrivals (`History.arrival_store`) less this.
        syncs = self.history.sync_store
        if syncs is not None:
            syncs += ARRIVAL.pack(n, time.monotonic_ns())
        got = self._collect(n, t, due, sync_number, frames + SYNC_FRAMES[counter - 1])
        if timing is not None and timing.waiting:
            timing.deliver(n, got, lambda cob_id: self._forget_rows(n, (cob_id,)), self._keep_late(got, n))
        result = self._record(n, t, counter, state, raw, sent, frames, got)
        self.plant.step(self.period_s)
        self.cycle = n + 1
        return result

    # The three phases of a cycle, apart so that a robot (`hilrig.engine.robot`) runs them for all its
    # modules around one SYNC: every module's RPDOs, one SYNC, every module's TPDOs, one physics
    # step. `step()` is the same sequence for one node, on the same `_sample` and `_record`.
    def begin_cycle(self, *, send: bool = True) -> CycleStart:
        """Sample the plant and send this cycle's RPDOs (before the SYNC); with send=False
        leave them in `unsent` for the caller to send ahead of the SYNC."""
        n, state, raw, due, sync_number, sent, frames = self._sample()
        unsent = frames
        if send and frames:
            send_frames(self.link, frames)
            unsent = b""
        return CycleStart(
            n, self.history.time_of(n), sync_counter(n), raw, state, due, sync_number, sent, frames, unsent
        )

    def collect_cycle(self, start: CycleStart) -> dict[int, tuple[Value, ...]]:
        """Wait for every TPDO due at this cycle's SYNC (after it was sent)."""
        return self._collect(start.cycle, start.t, start.due, start.sync_number, start.unsent)

    def end_cycle(self, start: CycleStart, got: dict[int, tuple[Value, ...]]) -> CycleResult:
        """Record the cycle in the history and apply its actuator outputs to the plant (the
        caller steps the plant and advances `cycle`)."""
        return self._record(
            start.cycle, start.t, start.counter, start.state, start.raw, start.sent, start.frames, got
        )

    # A robot exchanges every module's frames at once on one shared link (`Driver.share_link`)
    # and has each module judge its own frames of the cycle with these.
    @property
    def tpdo_cob_ids(self) -> Iterable[int]:
        """COB-IDs of the node's enabled TPDOs."""
        return self._tpdo_by_cob.keys()

    @property
    def decoders(self) -> Mapping[int, Decoder]:
        """The exchange's decoders of the node's TPDOs (`transport.Decoders`), by COB-ID."""
        return self._decoders

    def take_pending(self) -> list[tuple[int, bytes]]:
        """The TPDO frames polled since the last cycle (the cycle must `take` them)."""
        pending, self._pending = self._pending, []
        return pending

    def take(
        self,
        got: dict[int, tuple[Value, ...]],
        start: CycleStart,
        cob_id: int,
        data: bytes,
        between_syncs: bool = False,
    ) -> None:
        """One of the node's frames in the cycle `start` began that the exchange did not decode
        itself, judged as the node's own cycle judges it (a LockstepError for a TPDO the rules
        refuse); a TPDO taken goes into `got` and its rows."""
        self._take(got, start.cycle, start.t, start.due, start.sync_number, cob_id, data, between_syncs)

    def check_alive(self, start: CycleStart, got: dict[int, tuple[Value, ...]], guard: HangGuard) -> bool:
        """A quiet slice of the cycle's wait passed with TPDOs of the node due at its SYNC not in
        `got`: `_check_alive` (FirmwareError when its process died)."""
        return self._check_alive(start.cycle, start.t, start.due, got, guard)

    def forget_rows(self, n: int, got: Iterable[int]) -> None:
        """Take the rows of cycle `n` back out of the history for the node's TPDOs in `got`
        (COB-IDs, any node's)."""
        self._forget_rows(n, [cob_id for cob_id in got if cob_id in self._tpdo_by_cob])

    def _sample(self) -> tuple[int, Truth, SensorFrame, frozenset[int], int, tuple[PdoRow, ...], bytes]:
        """A cycle's first phase, nothing sent yet: (cycle, the plant's state, the sensor frame
        sampled from it, the TPDOs (COB-IDs) due at its SYNC, that SYNC's number since the node
        went operational, the RPDOs' rows, their frames joined in sending order)."""
        n = self.cycle
        plant = self.plant
        raw = plant.sense()
        state = plant.truth()
        if self.sensor_override is not None:
            raw = self.sensor_override(raw)
        if self._operational:
            sync_number = self._syncs_since_operational = self._syncs_since_operational + 1
            due = self._due_table[sync_number % len(self._due_table)]
            starts = self._sync_starts
            if starts is not None:  # TPDOs with a SYNC start value: by the counter
                due = due | starts.due(sync_counter(n))
        else:
            sync_number = 0
            due = _NOTHING_DUE
        sent, frames = self._rpdos_of_cycle(raw)
        return n, state, raw, due, sync_number, sent, frames

    def _record(
        self,
        n: int,
        t: float,
        counter: int,
        state: Truth,
        raw: SensorFrame,
        sent: tuple[PdoRow, ...],
        frames: bytes,
        got: dict[int, tuple[Value, ...]],
    ) -> CycleResult:
        """A cycle's last phase: its RPDOs and truth into the history (its TPDOs are in already,
        appended as they were decoded: `_collect`), its actuator outputs applied to the plant
        (None when the TPDOs carrying them did not come: the node not operational), and the
        result."""
        one = self._actuator_one
        if one is not None:
            values = got.get(one[0])
            outputs = None if values is None else (values[one[1]],)
        else:
            outputs = self._actuator(got)
        self.plant.apply(outputs)
        if self._rpdo_rows:  # none when the history keeps nothing
            append_frame_rows(frames, self._rpdo_rows, n)
        self.history.record_truth(state)
        return CycleResult(n, t, counter, raw, got, outputs, sent, state, self._tpdo_by_cob)

    def _collect(
        self, n: int, t: float, due: frozenset[int], sync_number: int, out: bytes = b""
    ) -> dict[int, tuple[Value, ...]]:
        """Send `out` (the cycle's frames not sent yet), then read the link until every TPDO
        due at this SYNC (COB-IDs in `due`) is in (the wall-clock bound is only a hang guard),
        then what is already queued behind them; TPDOs that are not cyclic (event-driven) are
        taken as they come (the firmware sends those a SYNC's cycle causes before its cyclic
        ones, so they are this cycle's; one sent between SYNCs is the next cycle's). A cyclic
        TPDO twice, one not due, or a frame of the wrong length is a LockstepError of this
        cycle. Returns the values by COB-ID, each also appended to its PDO's rows in the history
        as this cycle's (none of them when the cycle fails)."""
        got: dict[int, tuple[Value, ...]] = {}
        exchange, decoders = self._exchange, self._decoders
        assert exchange is not None, "configure() binds the exchange"
        try:
            if self._pending:
                if out:
                    send_frames(self.link, out)  # the SYNC is on the bus, as when no frame was pending
                    out = b""
                pending, self._pending = self._pending, []
                for cob_id, data in pending:  # polled between cycles: late or duplicate, unless acyclic
                    self._take(got, n, t, due, sync_number, cob_id, data, between_syncs=True)
            guard: HangGuard | None = None
            while True:
                # Due TPDOs of the usual length are decoded into `got` (and their rows) inside;
                # anything else comes back at once, in arrival order.
                frame = exchange(out, due, decoders, got, LIVENESS_SLICE_S, n)
                if frame is None:
                    return got
                out = b""
                if frame is not False:
                    self._take(got, n, t, due, sync_number, *frame)  # type: ignore[misc]
                    if due and not self._operational:  # it left operational (a heartbeat event)
                        due = frozenset(got)
                    continue
                if guard is None:
                    guard = HangGuard(self.tpdo_timeout_s, self.activity, LIVENESS_SLICE_S)
                if self._check_alive(n, t, due, got, guard):
                    return got  # given up on, and `on_problem` has it: the cycle ends without them
        except BaseException:
            self._forget_rows(n, got)
            raise

    def _take(
        self,
        got: dict[int, tuple[Value, ...]],
        n: int,
        t: float,
        due: frozenset[int],
        sync_number: int,
        cob_id: int,
        data: bytes,
        between_syncs: bool = False,
    ) -> None:
        """Any frame of cycle `n` but a due TPDO of the right length: EMCY, acyclic TPDO, or a
        problem (a LockstepError). A TPDO taken goes into `got` and its rows."""
        pdo = self._tpdo_by_cob.get(cob_id)
        if pdo is None:
            self._other_frame(cob_id, data)
            return
        values = self._decode(pdo, data)
        if values is None:
            problem = f"arrived with {len(data)} bytes, its mapping has {pdo.length}"
        elif not pdo.is_cyclic:
            self._keep(got, n, cob_id, values, data)
            return
        elif between_syncs:
            problem = "arrived between SYNCs"
        elif cob_id in got:
            problem = "arrived twice"
        elif not sync_number:
            problem = "arrived while the node is not operational (nothing is due)"
        elif cob_id not in due:
            problem = (
                f"arrived but is not due at SYNC {sync_number} since operational "
                f"(transmission type {pdo.transmission_type})"
            )
        else:  # a due TPDO after all (not one the exchange decoded itself)
            self._keep(got, n, cob_id, values, data)
            return
        if self.on_problem is None:
            raise self._error(n, t, f"{pdo.label} {problem}")
        self.on_problem(CycleProblem(n, t, f"{pdo.label} {problem}", refused=pdo))

    def _keep(
        self, got: dict[int, tuple[Value, ...]], n: int, cob_id: int, values: tuple[Value, ...], data: bytes
    ) -> None:
        """A TPDO of cycle `n` into `got` and its rows (what the exchange does in C)."""
        got[cob_id] = values
        decoder = self._decoders[cob_id]
        if len(decoder) >= 4:  # the history keeps rows
            append_row(decoder, n, data)  # type: ignore[arg-type]

    def _keep_late(
        self, got: dict[int, tuple[Value, ...]], n: int
    ) -> Callable[[int, tuple[Value, ...]], None]:
        """What the timed bus calls with each earlier cycle's TPDO it delivers in cycle `n`."""

        def keep(cob_id: int, values: tuple[Value, ...]) -> None:
            pdo = self._tpdo_by_cob[cob_id]
            self._keep(
                got, n, cob_id, values, pdo.frame(values)[CAN_HEADER_SIZE : CAN_HEADER_SIZE + pdo.length]
            )

        return keep

    def _check_alive(
        self, n: int, t: float, due: frozenset[int], got: dict[int, tuple[Value, ...]], guard: HangGuard
    ) -> bool:
        """A quiet slice of a wait for due TPDOs passed: FirmwareError if the node's process
        died, LockstepError once the hang guard gives up on the firmware (with `on_problem`:
        that problem to it, and True), HostStarvedError once it gives up on the host."""
        if self.liveness is not None:
            try:
                self.liveness()  # raises (e.g. FirmwareError) when the node's process died
            except FirmwareError as error:
                raise FirmwareError(f"cycle {n} (t = {t:.6g} s): {error}") from error
        try:
            why = guard.check(LIVENESS_SLICE_S)
        except HostStarvedError as error:
            raise HostStarvedError(f"cycle {n} (t = {t:.6g} s): {error}") from None
        if why is not None:
            by_cob = self._tpdo_by_cob
            missing = due.difference(got)
            labels = ", ".join(by_cob[c].label for c in sorted(missing, key=lambda c: by_cob[c].number))
            verb = "did" if len(missing) == 1 else "do"
            heartbeat = self.node.last_heartbeat
            hint = f"; last heartbeat: {heartbeat.name}" if heartbeat is not None else ""
            what = f"{labels} {verb} not arrive{why}{hint}"
            if self.on_problem is None:
                raise self._error(n, t, what)
            order = sorted(due, key=lambda c: by_cob[c].number)
            self.on_problem(
                CycleProblem(
                    n,
                    t,
                    what,
                    missing=tuple(by_cob[c] for c in order if c in missing),
                    received=tuple(by_cob[c] for c in order if c in got),
                )
            )
            return True
        return False

    def _forget_rows(self, n: int, got: Iterable[int]) -> None:
        """Take the rows of cycle `n` that `got`'s TPDOs left in the history back out."""
        by_cob = self._tpdo_by_cob
        for cob_id in got:
            self.history.take_back(by_cob[cob_id], n)

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
    "HANG_CAP_FACTOR",
    "CycleProblem",
    "CycleResult",
    "CycleStart",
    "HangGuard",
    "History",
    "LockstepDriver",
    "cycles_for",
    "resolve_truth_name",
    "sync_counter",
]
