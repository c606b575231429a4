"""The scenario assertions on recorded histories: what passes, and what a failure says."""

from __future__ import annotations

import numpy as np
import pytest

from hilrig.expect import Expect, ScenarioAssertion

PERIOD_S = 0.001
EVIDENCE = "trace out/x/trace.rrd, bus log out/x/bus.log"


class RecordedHistory:
    """What a Rig's history() answers, from arrays the test sets."""

    def __init__(self, **series: tuple[np.ndarray, np.ndarray]) -> None:
        self._series = series

    def history(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        return self._series[name]

    @property
    def period_s(self) -> float:
        return PERIOD_S


def first_order_step(target: float, tau_s: float, seconds: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(round(seconds / PERIOD_S)) * PERIOD_S
    return t, target * (1.0 - np.exp(-t / tau_s))


def expect_for(**series: tuple[np.ndarray, np.ndarray]) -> Expect:
    return Expect(RecordedHistory(**series), evidence=EVIDENCE)


def test_settles_within_returns_the_settling_time_and_names_the_late_sample() -> None:
    expect = expect_for(v=first_order_step(5.0, tau_s=0.1))
    settled = expect.settles_within("v", target=5.0, tolerance=0.02, by_s=0.5)
    assert settled == pytest.approx(0.1 * np.log(50), abs=2 * PERIOD_S)  # e^(-t/tau) = 2 %
    with pytest.raises(ScenarioAssertion) as failure:
        expect.settles_within("v", target=5.0, tolerance=0.02, by_s=0.3)
    message = str(failure.value)
    assert "v: expected to settle within 2.0% of 5 (±0.1) by t = 0.300 s, got 4.75" in message
    assert "cycle 300" in message and message.endswith(EVIDENCE)


def test_overshoot_below_measures_the_peak_beyond_the_target() -> None:
    t = np.arange(1000) * PERIOD_S
    v = 2.0 * (1.0 - np.exp(-t / 0.05) * np.cos(40.0 * t))  # under-damped: peaks above 2
    overshoot = expect_for(v=(t, v)).overshoot_below("v", target=2.0, limit=0.5)
    assert overshoot == pytest.approx((v.max() - 2.0) / 2.0)
    with pytest.raises(ScenarioAssertion, match=r"expected overshoot below 5\.0% of 2, got \d+\.\d%"):
        expect_for(v=(t, v)).overshoot_below("v", target=2.0, limit=0.05)
    # Negative targets overshoot downwards.
    assert expect_for(v=(t, -v)).overshoot_below("v", target=-2.0, limit=0.5) == pytest.approx(overshoot)


def test_stays_within_names_the_first_sample_outside() -> None:
    t = np.arange(10) * PERIOD_S
    v = np.array([0.0, 0.5, 0.9, 0.97, 0.99, 0.5, 0.0, 0.0, 0.0, 0.0])
    expect_for(v=(t, v)).stays_within("v", -0.95, 0.95, after_s=0.005)
    with pytest.raises(ScenarioAssertion, match=r"within \[-0\.95, 0\.95\], got 0\.97 at t = 0\.003 s"):
        expect_for(v=(t, v)).stays_within("v", -0.95, 0.95)


def test_eventually_and_never() -> None:
    t = np.arange(10) * PERIOD_S
    v = np.array([0, 0, 0, 1, 1, 1, 0, 0, 0, 0], dtype=float)
    expect = expect_for(flag=(t, v))
    assert expect.eventually("flag", lambda x: x == 1, "flag set") == pytest.approx(0.003)
    with pytest.raises(ScenarioAssertion, match=r"expected flag set by t = 0\.002 s, first at t = 0\.003 s"):
        expect.eventually("flag", lambda x: x == 1, "flag set", by_s=0.002)
    with pytest.raises(ScenarioAssertion, match="never happened"):
        expect.eventually("flag", lambda x: x == 1, "flag set", after_s=0.006)
    expect.never("flag", lambda x: x == 1, "set", after_s=0.006)
    with pytest.raises(ScenarioAssertion, match=r"expected never set, got 1 at t = 0\.003 s"):
        expect.never("flag", lambda x: x == 1, "set")


def test_average_rate_within_takes_the_slope_through_jittered_samples() -> None:
    # A joint at 2 rad/s sampled at irregular times (ticks 20 to 150 ms apart), each sample
    # stamped up to 100 ms late: single differences swing wildly, the slope does not.
    rng = np.random.default_rng(7)
    taken = np.cumsum(rng.uniform(0.02, 0.15, size=40))
    received = taken + rng.uniform(0.0, 0.1, size=taken.size)
    expect = expect_for(position=(received, 2.0 * taken))
    differences = np.diff(2.0 * taken) / np.diff(received)
    assert differences.min() < 1.0 and differences.max() > 4.0
    rate = expect.average_rate_within("position", target=2.0, tolerance=0.05, after_s=received[10])
    assert rate == pytest.approx(2.0, rel=0.05)
    with pytest.raises(ScenarioAssertion) as failure:
        expect.average_rate_within("position", target=3.0, tolerance=0.10)
    message = str(failure.value)
    assert "position: expected to change at 3/s on average within 10.0% (±0.3), got 1.9" in message
    assert "least-squares slope of 40 samples" in message and message.endswith(EVIDENCE)


def test_average_rate_within_needs_samples_spread_over_time() -> None:
    t = np.arange(10) * PERIOD_S
    expect = expect_for(position=(t, t))
    with pytest.raises(ScenarioAssertion, match=r"no samples recorded after t = 1\.000 s"):
        expect.average_rate_within("position", target=1.0, tolerance=0.1, after_s=1.0)
    with pytest.raises(ScenarioAssertion, match=r"expected samples spread over time .* got 1 "):
        expect.average_rate_within("position", target=1.0, tolerance=0.1, after_s=0.009)
