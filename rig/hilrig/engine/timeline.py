"""A scenario's clock: `run`, `run_until`, `at` and `before_each_cycle` over one cycle at a time.

Shared by `hilrig.engine.rig.Rig` (one board) and `hilrig.engine.robot.Robot` (N modules around one SYNC), so
a scenario reads the same whichever it drives. In lockstep, times are simulation time and
events are keyed by cycle (exact); in real time (a Rig only), by wall seconds on `t`'s timeline.
"""

from __future__ import annotations

import heapq
import itertools
from collections.abc import Callable
from typing import Any

from hilrig.engine.lockstep import cycles_for
from hilrig.errors import ScenarioTimeoutError

Event = Callable[[Any], object]
"""Called with the rig (or robot) whose clock fired it."""


class CycleRunner:
    """The clock of a scenario over `_step()` (one cycle). A subclass provides `cycle`, `t`,
    `period_us`, `_step()` and, when `realtime`, `_wall_now()`; it calls `_init_timeline()`."""

    realtime = False

    def _init_timeline(self) -> None:
        self._events: list[tuple[float, int, Event]] = []
        self._event_order = itertools.count()
        self._cycle_hooks: list[Event] = []

    @property
    def cycle(self) -> int:
        raise NotImplementedError

    @property
    def t(self) -> float:
        raise NotImplementedError

    @property
    def period_us(self) -> int:
        raise NotImplementedError

    def _step(self) -> None:
        raise NotImplementedError

    def _wall_now(self) -> float:
        raise NotImplementedError

    def run(self, *, seconds: float | None = None, cycles: int | None = None) -> None:
        """Run for `seconds` (simulation time in lockstep, wall time in real time) or a number
        of `cycles` (real time: ticks)."""
        if (seconds is None) == (cycles is None):
            raise TypeError("run() takes exactly one of seconds= or cycles=")
        if self.realtime and seconds is not None:
            end = self._wall_now() + check_seconds(seconds)
            while not self._reached(end):
                self._advance()
            self._fire_events()
            return
        count = cycles if cycles is not None else cycles_for(seconds or 0.0, self.period_us)
        if count < 0:
            raise ValueError(f"cycles: expected >= 0, got {count}")
        # _advance() inlined: this loop is the rig's per-cycle path, and in the emulated VM a few
        # Python calls more per cycle showed (A/B against fafd332: 9 % fewer cycles/s, on par
        # with this loop and LockstepDriver.step calling _collect directly).
        events, hooks, step, fire = self._events, self._cycle_hooks, self._step, self._fire_events
        for _ in range(count):
            if events:
                fire()
            for hook in hooks:
                hook(self)
            step()
        self._fire_events()  # an event at exactly the end time has happened when run() returns

    def run_until(
        self, condition: Callable[[Any], bool], *, within_s: float, what: str = "condition"
    ) -> float:
        """Run until `condition(self)` holds (checked after each cycle); return `t` then.

        Raises ScenarioTimeoutError when it does not hold within `within_s` of simulation time
        (wall time in real time).
        """
        if self.realtime:
            end = self._wall_now() + check_seconds(within_s)
            while not self._reached(end):
                self._advance()
                if condition(self):
                    return self.t
        for _ in range(0 if self.realtime else cycles_for(within_s, self.period_us)):
            self._advance()
            if condition(self):
                return self.t
        raise ScenarioTimeoutError(
            f"expected {what} within {within_s:g} s, not met at t = {self.t:.6g} s (cycle {self.cycle})"
        )

    def before_each_cycle(self, callback: Event) -> None:
        """Call `callback(self)` before every later cycle (tick), after that cycle's events."""
        self._cycle_hooks.append(callback)

    def at(self, seconds: float, callback: Event) -> None:
        """Call `callback(self)` when `t` reaches `seconds` (before that cycle or tick)."""
        key: float = seconds if self.realtime else cycles_for(seconds, self.period_us)
        if key < self._now_key():
            raise ValueError(f"at({seconds}): already past, t = {self.t:.6g} s")
        heapq.heappush(self._events, (key, next(self._event_order), callback))

    def _advance(self) -> None:
        """The events due now, the per-cycle hooks, one cycle."""
        self._fire_events()
        for hook in self._cycle_hooks:
            hook(self)
        self._step()

    def _reached(self, end_s: float) -> bool:
        """Real time: has the last tick reached `end_s` (or a first tick yet to come)?"""
        return self.cycle > 0 and self.t >= end_s - 1e-9

    def _now_key(self) -> float:
        """Where events are on their key: the cycle (lockstep, exact) or t (real time)."""
        return self.t + 1e-9 if self.realtime else self.cycle

    def _fire_events(self) -> None:
        while self._events and self._events[0][0] <= self._now_key():
            _, _, callback = heapq.heappop(self._events)
            callback(self)


def check_seconds(seconds: float) -> float:
    cycles_for(seconds, 1)  # the same finite, non-negative check
    return seconds


__all__ = ["CycleRunner", "Event", "check_seconds"]
