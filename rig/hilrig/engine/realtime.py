"""The real-time driver: the rig keeps its own wall-clock period, as beside a real board.

For the firmware in `--mode free` (its own absolute-deadline timer) and for real boards. One
tick (index n, at wall time t0 + n * period on an absolute grid; a late tick does not shift
the ones after it, ticks missed entirely are counted in `overruns`):

1. wait for the tick's deadline (`time.monotonic()`, or the clock the caller passes);
2. take the TPDO values that arrived since the last tick, the latest of each: real time
   cannot wait for an answer, so what the node sent in reply to the last SYNC is read now;
3. physics on: step the plant by the *measured* wall time since the last tick, with the
   latest duty the node commanded (0 while it is not operational); at most `max_step_periods`
   periods, so a machine too slow for the plant (the physics' cost grows with dt) does not
   spiral into ever longer ticks: the time the plant skipped is counted in `physics_lost_s`;
4. physics on: sample the plant and send the sensor RPDO; always: the setpoint stream and
   any RPDO a scenario changed;
5. send SYNC; in free mode it runs no cycle, it only asks for the synchronous TPDOs, which
   report the node's latest state and arrive before the next tick.

History is on the wall-clock timeline: t = seconds since the first tick, the tick's own time
(not n * period). Physics off (bring-up): no sensor RPDO goes out and the plant stands still;
the rig only commands and observes.

Without a rig (a board on its own, no master: `hilrig watch`, `record`, `capture`), the
`SyncProducer` is the bus's SYNC producer on the same tick grid (`TickGrid`) with the same
counter rule (`sync_counter`).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable
from typing import Self

import numpy as np

from boardproto.cia301 import NmtState
from hilrig.engine.driver import (
    CycleResult,
    Driver,
    History,
    PdoRow,
    Value,
    sync_counter,
    sync_frame,
)
from hilrig.errors import RealTimeError
from hilrig.plants.interface import Plant
from hilrig.wire.node import BoardNode
from hilrig.wire.transport import PdoLayout


class TickGrid:
    """Ticks on an absolute wall-clock grid, t0 + k * period: a late tick does not shift the
    ones after it, and the ticks that passed entirely while late are skipped and counted in
    `overruns`. The caller waits for `deadline` on its own clock, then says `reached(now)`."""

    def __init__(self, period_s: float) -> None:
        self.period_s = period_s
        self.t0: float | None = None
        """The clock at tick 0 [s]; None before `start`."""
        self.overruns = 0
        """Whole ticks skipped (the caller was late by more than a period)."""
        self._next = 0  # index of the next tick

    def start(self, now: float, *, first: int = 0) -> None:
        """Tick 0 is at `now`; the first tick to wait for is `first`."""
        self.t0 = now
        self._next = first

    @property
    def deadline(self) -> float:
        """The clock of the next tick [s]."""
        assert self.t0 is not None, "TickGrid.start first"
        return self.t0 + self._next * self.period_s

    def reached(self, now: float) -> None:
        """The next tick was reached at `now` (at or after its deadline): the ticks that passed
        meanwhile are skipped, the grid stays where it was."""
        missed = int((now - self.deadline) // self.period_s)
        if missed > 0:
            self.overruns += missed
            self._next += missed
        self._next += 1


class SyncProducer:
    """Sends SYNC every `period_s` from a thread of its own until stopped (a context manager):
    on a `TickGrid`, the counter `sync_counter` of the SYNCs sent so far (1..240, wrapping), the
    first one period after the start. A SYNC whose tick passed while the thread was late is
    skipped and counted in `overruns` (the counter counts what went out). The first error of
    `send` stops it; it waits in `error` for the caller to raise. `clock` returns seconds
    (monotonic), `wait(seconds)` blocks about that long: both default to the wall clock (a stop
    wakes the wait), tests pass a clock they own and call `run()` on their own thread."""

    def __init__(
        self,
        send: Callable[[int], None],
        period_s: float,
        *,
        clock: Callable[[], float] = time.monotonic,
        wait: Callable[[float], object] | None = None,
    ) -> None:
        self._send = send
        self._stop = threading.Event()
        self.clock = clock
        self.wait = wait if wait is not None else self._stop.wait
        self.grid = TickGrid(period_s)
        self.sent = 0
        """SYNCs sent."""
        self.error: BaseException | None = None
        self._thread = threading.Thread(target=self.run, name="sync-producer", daemon=True)

    @property
    def overruns(self) -> int:
        """SYNCs skipped: their tick passed while the producer was late."""
        return self.grid.overruns

    def __enter__(self) -> Self:
        self._thread.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.stop()
        self._thread.join()

    def stop(self) -> None:
        self._stop.set()

    def run(self) -> None:
        """Send until stopped or `send` fails (the thread's body)."""
        grid = self.grid
        grid.start(self.clock(), first=1)
        while not self._stop.is_set():
            now = self.clock()
            while now < grid.deadline:
                self.wait(grid.deadline - now)
                if self._stop.is_set():
                    return
                now = self.clock()
            grid.reached(now)
            try:
                self._send(sync_counter(self.sent))
            except Exception as error:  # surfaced by the caller's loop
                self.error = error
                return
            self.sent += 1


class WallHistory(History):
    """`History` whose cycle times are the measured tick times, not cycle * period."""

    def __init__(self, period_us: int, *, plant: Plant | None = None) -> None:
        super().__init__(period_us, plant=plant)
        self._tick_times: list[float] = []

    def record_tick(self, t: float) -> None:
        self._tick_times.append(t)

    def time_of(self, cycle: int) -> float:
        """The wall time of recorded tick `cycle` [s since the first tick]."""
        return self._tick_times[cycle]

    def _times(self, cycles: Iterable[int]) -> np.ndarray:
        # Only the ticks spanned are converted: the tracer asks for each batch's cycles, and the
        # whole list grows for as long as the rig runs.
        indexes = np.fromiter(cycles, dtype=np.int64)
        if not len(indexes):
            return np.empty(0)
        first, last = int(indexes.min()), int(indexes.max())
        return np.asarray(self._tick_times[first : last + 1], dtype=float)[indexes - first]


class RealTimeDriver(Driver):
    """Runs real-time ticks between a `BoardNode` and the joint plant (or no plant).

    A sibling of `LockstepDriver` behind the same interface (configure, step, history, latest,
    RPDO values), so `Rig` drives either. `clock` returns seconds (monotonic); `wait(seconds)`
    blocks about that long: both default to the wall clock, tests pass a clock they own.
    physics=False: no sensor RPDO, no plant step, and the mapping need not carry the HIL
    inputs/output. tpdo_timeout_s: while the node is operational, a hang guard on its TPDOs
    going silent. max_step_periods: the longest plant step, in periods (see the module doc).
    What the node sent waits in the link's kernel queue until the tick takes it, so a busy rig
    loses nothing and needs no receive thread.
    """

    needs_sync_actuator = False  # any TPDO carrying the actuator fields will do, synchronous or not

    def __init__(
        self,
        node: BoardNode,
        plant: Plant,
        *,
        period_us: int,
        physics: bool = True,
        tpdo_timeout_s: float = 5.0,
        liveness: Callable[[], None] | None = None,
        max_step_periods: float = 5.0,
        clock: Callable[[], float] = time.monotonic,
        wait: Callable[[float], object] | None = None,
    ) -> None:
        self.physics = physics
        super().__init__(node, plant, period_us=period_us, tpdo_timeout_s=tpdo_timeout_s, liveness=liveness)
        self.history: WallHistory = WallHistory(period_us, plant=plant)
        self.clock = clock
        self.wait = wait if wait is not None else threading.Event().wait  # never set: a bounded sleep
        self.max_step_periods = max_step_periods
        self.physics_lost_s = 0.0
        """Wall time the plant did not simulate: steps cut to max_step_periods periods [s]."""
        self._ticks = TickGrid(self.period_s)
        self._elapsed = 0.0
        self._last_rx = 0.0
        self._outputs: tuple[Value, ...] | None = None

    @property
    def overruns(self) -> int:
        """Whole ticks missed (the rig was late by more than a period, or outside run())."""
        return self._ticks.overruns

    @property
    def needs_plant_io(self) -> bool:
        return self.physics

    @property
    def t(self) -> float:
        """Wall time of the last tick [s since the first tick]; 0 before any."""
        return self._elapsed

    def now(self) -> float:
        """The clock now [s since the first tick]; 0 before it."""
        t0 = self._ticks.t0
        return 0.0 if t0 is None else self.clock() - t0

    def node_entered(self, state: NmtState) -> None:
        super().node_entered(state)
        self._last_rx = self.clock()  # the silence guard counts from here

    # --- One tick -----------------------------------------------------------------------
    def _take_latest(self) -> tuple[PdoRow, ...]:
        """Every TPDO that arrived since the last tick, the latest of each (EMCYs dispatched)."""
        latest: dict[PdoLayout, tuple[Value, ...]] = {}
        pending, self._pending = self._pending, []
        recv = self.link.recv
        by_cob = self._tpdo_by_cob
        frames = iter(pending)
        while True:
            frame = next(frames, None)
            if frame is None:
                frame = recv(0.0)
                if frame is None:
                    break
            cob_id, data = frame
            pdo = by_cob.get(cob_id)
            if pdo is None:
                self._other_frame(cob_id, data)
                continue
            values = self._decode(pdo, data)
            if values is not None:
                latest[pdo] = values
        return tuple(sorted(latest.items(), key=lambda row: row[0].number))

    def step(self) -> CycleResult:
        n = self.cycle
        now = self._wait_for_tick()
        if self.liveness is not None:
            self.liveness()  # raises (e.g. FirmwareError) when the node's process died
        assert self._ticks.t0 is not None
        elapsed = now - self._ticks.t0
        dt = elapsed - self._elapsed

        received = self._take_latest()
        if received:
            self._last_rx = now
        elif self._operational and now - self._last_rx > self.tpdo_timeout_s:
            raise RealTimeError(
                f"tick {n} (t = {elapsed:.6g} s): no TPDO from node 0x{self.node.node_id:02X} for "
                f"{now - self._last_rx:.3g} s"
            )
        if not self._operational:
            self._outputs = None  # the plant's safe default, as a driver whose commands stopped
        elif self._actuator_pdos:
            got = {pdo.cob_id: values for pdo, values in received if pdo in self._actuator_pdos}
            if len(got) == len(self._actuator_pdos):  # otherwise the last tick's hold
                self._outputs = self._actuator(got)

        raw = None
        if self.physics:
            step_s = min(dt, self.max_step_periods * self.period_s)
            self.physics_lost_s += dt - step_s
            if step_s > 0.0:
                self.plant.apply(self._outputs)
                self.plant.step(step_s)
            raw = self.plant.sense()
            if self.sensor_override is not None:
                raw = self.sensor_override(raw)
        state = self.plant.truth() if self.physics else None
        sent = self._transmit_rpdos(raw)
        counter = sync_counter(n)
        self.link.send(sync_frame(counter))
        if self._operational:
            self._syncs_since_operational += 1

        self._elapsed = elapsed
        self.history.record_tick(elapsed)
        if self.physics:
            self.history.record_truth(state)
        self.history.record_rows(n, received, sent)
        self.cycle = n + 1
        return CycleResult(
            cycle=n,
            time_s=elapsed,
            sync_counter=counter,
            raw=raw,
            received_rows=received,
            outputs=self._outputs,
            sent_rows=sent,
            truth=state,
        )

    def _wait_for_tick(self) -> float:
        """Block until this tick's absolute deadline (t0 + k * period); return the clock then."""
        ticks = self._ticks
        if ticks.t0 is None:
            ticks.start(self.clock())
        deadline = ticks.deadline
        now = self.clock()
        while now < deadline:
            self.wait(deadline - now)
            now = self.clock()
        ticks.reached(now)  # the ticks that passed are skipped: the grid stays where it was
        return now


__all__ = ["RealTimeDriver", "SyncProducer", "TickGrid", "WallHistory"]
