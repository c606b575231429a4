"""Assertions for scenarios that read like control engineering, on a field's recorded history.

Every check works in simulation time, on what the rig recorded, so it is exact and repeatable.
A failure raises `ScenarioAssertion` (an AssertionError) whose message shows the numbers, the
simulation time and cycle, and the paths of the scenario's trace and bus log; given a `picture`
(`hilrig.observe.picture.FailurePictures`), it also draws the field against what was expected
and the moment it failed, and names the PNG (`ScenarioAssertion.pictures`):

    expect = Expect(rig, evidence="trace out/scenarios/x/trace.rrd, bus log .../bus.log")
    expect.settles_within("output_velocity", target=5.0, tolerance=0.02, by_s=1.5)
    expect.overshoot_below("output_velocity", target=5.0, limit=0.25, after_s=0.5)
    expect.stays_within("motor_duty_command", -0.95, 0.95)
    expect.average_rate_within("output_position", target=2.0, tolerance=0.15, after_s=2.0)
    t = expect.eventually("safe_state", lambda v: v == 1, "safe_state == 1")
    expect.never("fault_flags", lambda v: v != 0, "a fault")
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np


class ScenarioAssertion(AssertionError):
    """A scenario expectation did not hold; the message carries the numbers and the evidence,
    `pictures` the PNGs drawn of it."""

    def __init__(self, message: str, pictures: tuple[Path, ...] = ()) -> None:
        super().__init__(message)
        self.pictures = pictures


class PictureUnavailable(Exception):
    """A picture of a failed check cannot be drawn here (a part is not installed); the message
    says what to install. The check's own failure still reads whole, with this line after it."""


@dataclass(frozen=True)
class FailedCheck:
    """What a picture of a failed check shows: the series looked at, the band of values it was
    expected in (from `band_from_s` on; None for a check with no band), and when it failed."""

    check: str
    name: str
    t: np.ndarray
    v: np.ndarray
    band: tuple[float, float] | None
    band_from_s: float
    at_s: float | None
    message: str


Picture = Callable[[FailedCheck], Path | None]
"""Draws a failed check and returns the PNG's path (None: it could not be drawn; PictureUnavailable:
it cannot be drawn here, the message says why)."""


class History(Protocol):
    def history(self, name: str) -> tuple[np.ndarray, np.ndarray]: ...

    @property
    def period_s(self) -> float: ...


@dataclass
class Expect:
    """Checks on the histories a `Rig` recorded. `evidence` names the trace and bus log."""

    rig: History
    evidence: str = ""
    picture: Picture | None = None

    def _fail(
        self,
        message: str,
        series: tuple[np.ndarray, np.ndarray] | None = None,
        *,
        name: str = "",
        band: tuple[float, float] | None = None,
        band_from_s: float = 0.0,
        at_s: float | None = None,
    ) -> ScenarioAssertion:
        pictures: tuple[Path, ...] = ()
        if self.picture is not None and series is not None:
            caller = inspect.currentframe()
            check = caller.f_back.f_code.co_name if caller and caller.f_back else "check"  # settles_within...
            try:
                drawn = self.picture(FailedCheck(check, name, *series, band, band_from_s, at_s, message))
            except PictureUnavailable as missing:
                drawn = None
                message += f"; {missing}"
            if drawn is not None:
                pictures = (drawn,)
                message += f"; picture {drawn}"
        suffix = f"; {self.evidence}" if self.evidence else ""
        return ScenarioAssertion(message + suffix, pictures)

    def _series(self, name: str, after_s: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        t, v = self.rig.history(name)
        keep = t >= after_s - 1e-12
        t, v = t[keep], v[keep].astype(float)
        if t.size == 0:
            raise self._fail(f"{name}: no samples recorded after t = {after_s:.3f} s")
        return t, v

    def _at(self, t: float) -> str:
        return f"t = {t:.3f} s (cycle {round(t / self.rig.period_s)})"

    def settles_within(
        self, name: str, *, target: float, tolerance: float, by_s: float, after_s: float = 0.0
    ) -> float:
        """From `by_s` on, `name` stays within `tolerance` (a fraction of |target|) of `target`.
        Returns the settling time: the last time it was outside the band, after `after_s`."""
        t, v = self._series(name, after_s)
        band = abs(target) * tolerance
        outside = np.abs(v - target) > band
        late = outside & (t >= by_s - 1e-12)
        if late.any():
            i = int(np.argmax(late))
            raise self._fail(
                f"{name}: expected to settle within {tolerance:.1%} of {target:g} (±{band:g}) by "
                f"t = {by_s:.3f} s, got {v[i]:.4g} at {self._at(t[i])}",
                (t, v), name=name, band=(target - band, target + band), band_from_s=by_s, at_s=float(t[i]),
            )
        if not outside.any():
            return float(t[0])
        return float(t[np.nonzero(outside)[0][-1]] + self.rig.period_s)

    def overshoot_below(self, name: str, *, target: float, limit: float, after_s: float = 0.0) -> float:
        """The peak beyond `target` (as a fraction of |target|) stays below `limit`. Returns it."""
        t, v = self._series(name, after_s)
        direction = 1.0 if target >= 0 else -1.0
        i = int(np.argmax(direction * v))
        overshoot = max(0.0, direction * (v[i] - target) / abs(target))
        if overshoot >= limit:
            bound = target + direction * limit * abs(target)
            raise self._fail(
                f"{name}: expected overshoot below {limit:.1%} of {target:g}, got {overshoot:.1%} "
                f"(peak {v[i]:.4g}) at {self._at(t[i])}",
                (t, v), name=name, band=(min(target, bound), max(target, bound)), band_from_s=after_s,
                at_s=float(t[i]),
            )
        return overshoot

    def stays_within(self, name: str, low: float, high: float, *, after_s: float = 0.0) -> None:
        """Every sample after `after_s` lies in [low, high]."""
        t, v = self._series(name, after_s)
        bad = (v < low) | (v > high)
        if bad.any():
            i = int(np.argmax(bad))
            raise self._fail(
                f"{name}: expected within [{low:g}, {high:g}], got {v[i]:.4g} at {self._at(t[i])}",
                (t, v), name=name, band=(low, high), band_from_s=after_s, at_s=float(t[i]),
            )

    def average_rate_within(
        self, name: str, *, target: float, tolerance: float, after_s: float = 0.0
    ) -> float:
        """The average rate of change of `name` after `after_s` (the least-squares slope against
        time, per second) is within `tolerance` (a fraction of |target|) of `target`. Returns it.

        Made for real time: a position's slope over a long window is immune to the jitter of
        when each sample was taken and received, which a velocity estimate carries."""
        t, v = self._series(name, after_s)
        if t.size < 2 or t[-1] - t[0] <= 0.0:
            raise self._fail(
                f"{name}: expected samples spread over time after t = {after_s:.3f} s to take a rate "
                f"from, got {t.size} at {self._at(t[0])}"
            )
        rate = float(np.polyfit(t, v, 1)[0])
        band = abs(target) * tolerance
        if not abs(rate - target) <= band:
            raise self._fail(
                f"{name}: expected to change at {target:g}/s on average within {tolerance:.1%} (±{band:g}), "
                f"got {rate:.4g}/s (least-squares slope of {t.size} samples from t = {t[0]:.3f} s to "
                f"{self._at(t[-1])})",
                (t, v), name=name, at_s=float(t[-1]),
            )
        return rate

    def eventually(
        self,
        name: str,
        condition: Callable[[float], bool],
        what: str,
        *,
        after_s: float = 0.0,
        by_s: float | None = None,
    ) -> float:
        """The first time after `after_s` that `condition` holds (and not later than `by_s`)."""
        t, v = self._series(name, after_s)
        for ti, vi in zip(t, v, strict=True):
            if condition(float(vi)):
                if by_s is not None and ti > by_s + 1e-12:
                    raise self._fail(
                        f"{name}: expected {what} by t = {by_s:.3f} s, first at {self._at(ti)}",
                        (t, v), name=name, at_s=float(ti),
                    )
                return float(ti)
        raise self._fail(
            f"{name}: expected {what} after t = {after_s:.3f} s, never happened "
            f"(last value {v[-1]:.4g} at {self._at(t[-1])})",
            (t, v), name=name, at_s=float(t[-1]),
        )

    def never(
        self, name: str, condition: Callable[[float], bool], what: str, *, after_s: float = 0.0
    ) -> None:
        """`condition` holds at no sample after `after_s`."""
        t, v = self._series(name, after_s)
        for ti, vi in zip(t, v, strict=True):
            if condition(float(vi)):
                raise self._fail(
                    f"{name}: expected never {what}, got {vi:.4g} at {self._at(ti)}",
                    (t, v), name=name, at_s=float(ti),
                )
