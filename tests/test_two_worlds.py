"""One scenario file, two worlds. Each scenario is a function of (rig, expect), written once:

- lockstep: the firmware in `--mode lockstep`, one cycle per SYNC, exact simulation time (and
  the tight assertions only exact time allows);
- real time: the firmware in `--mode free` with its own 100 Hz timer and the rig ticking at
  50 Hz in wall-clock time, the physics stepped by the measured time between ticks, exactly as
  the rig would stand beside a real board (in the software-emulated VM, Python cannot keep
  1 kHz: hence the longer periods, conftest.REALTIME_*_PERIOD_US);
- a real board: the same real-time tests with `--hil-interface socketcan --hil-channel can0`
  (README, "Pointing a scenario at a real board"); the rig then opens that interface and starts
  no firmware.

The real-time assertions are what wall-clock time on a loaded machine allows: loose bands at
the end, limits never crossed, no settling times.
"""

from __future__ import annotations

import numpy as np
import pytest

from hilrig.expect import Expect
from hilrig.node import NmtState
from hilrig.physics import JointParams
from hilrig.rig import Rig

pytestmark = pytest.mark.bus

VELOCITY_MODE = 1.0
SETPOINT_RAD_S = 2.0
GEAR_RATIO = JointParams().gear_ratio
HOLD_S = 1.5
DUTY_LIMIT = 0.95
REALTIME_KP, REALTIME_KI = 0.05, 0.5


# --- The scenarios, written once ----------------------------------------------------------------
def arm(rig: Rig) -> None:
    """Sensors flowing, faults cleared. A free-running node counts its sensors silent from its
    first cycle, so by the time the rig ticks it has latched the stale-sensor faults (a real
    board that booted before its master did the same); clearing is what a master does first."""
    if rig.realtime:
        # Real time inside a software-emulated VM: a tick can come 100 ms late, longer than the
        # default 20-cycle encoder silence at a 10 ms period. Allow 2 s (what real time allows
        # here); lockstep keeps the defaults, which its scenarios check exactly.
        for name in ("encoder_stale_cycles", "thermistor_stale_cycles"):
            rig.set(name, 200.0)
    rig.run(seconds=0.2)
    rig.set("fault_clear", 1.0)
    if rig.realtime:
        # The node clears in its next cycle, but its answer reaches the rig a tick or more later
        # (two clocks, and a receive thread that lags on a loaded machine: seen in CI, where the
        # bus log had the cleared flags while the rig still held the old ones): wait for it.
        rig.run_until(lambda r: r.field("safe_state") == 0.0, within_s=2.0, what="no fault after a clear")
    else:
        rig.run(seconds=0.1)
    assert rig.field("safe_state") == 0.0, (
        f"expected no fault after a clear, got fault_flags {rig.field('fault_flags')}"
    )


def velocity_hold(rig: Rig, expect: Expect) -> float:
    """Velocity mode, 2 rad/s at the joint, for 1.5 s: over the last 0.5 s the gearbox-side
    speed (the regulated one) is within 15 % of the target on average, and the duty command
    stays inside its limits all along. Single samples are not held to the band: in real time
    each position arrives with the jitter of two unsynchronised clocks, and the firmware's
    velocity estimate carries it. Returns the mean joint speed over the last 0.5 s [rad/s]."""
    arm(rig)
    rig.set("control_mode", VELOCITY_MODE)
    rig.set("velocity_setpoint", SETPOINT_RAD_S)
    start = rig.t
    rig.run(seconds=HOLD_S)
    expect.stays_within("motor_duty_command", -DUTY_LIMIT, DUTY_LIMIT, after_s=start)
    t, motor = rig.history("motor_velocity")
    late = motor[t >= rig.t - 0.5]
    mean = float(np.mean(late) / GEAR_RATIO) if late.size else float("nan")
    assert abs(mean - SETPOINT_RAD_S) <= 0.15 * SETPOINT_RAD_S, (
        f"expected the joint speed over the last 0.5 s within 15 % of {SETPOINT_RAD_S} rad/s on "
        f"average, got {mean:.3f} rad/s ({late.size} samples) at t = {rig.t:.3f} s; {expect.evidence}"
    )
    return mean


def observe_and_command(rig: Rig, expect: Expect) -> int:
    """Bring-up: the node is operational, its TPDOs keep coming, a parameter written by SDO
    reads back, and the rig sends no sensor frame. Returns the TPDO1 count in 0.5 s."""
    kp = rig.read("velocity_kp")
    rig.set("velocity_kp", kp)  # the value it has: harmless on any board
    assert rig.read("velocity_kp") == pytest.approx(kp)
    rig.run(seconds=0.5)
    assert rig.nmt_state is NmtState.OPERATIONAL, f"expected OPERATIONAL, got {rig.nmt_state}"
    t, _ = rig.history("motor_duty")
    assert t.size > 0, f"expected TPDO1 (motor_duty) in 0.5 s, got none; {expect.evidence}"
    assert rig.sent("motor_encoder_counts")[0].size == 0, "expected no sensor frame without physics"
    return int(t.size)


# --- Lockstep ------------------------------------------------------------------------------------
def test_velocity_hold_lockstep(make_scenario) -> None:
    s = make_scenario()
    mean = velocity_hold(s.rig, s.expect)
    # Exact time allows more: the tight band of test_joint, and the exact cycle count.
    start = s.rig.t - HOLD_S
    s.expect.settles_within(
        "motor_velocity", target=SETPOINT_RAD_S * GEAR_RATIO, tolerance=0.02, by_s=start + 0.5, after_s=start
    )
    assert s.rig.cycle == round((0.3 + HOLD_S) / s.rig.period_s)
    print(f"\nlockstep: {s.rig.cycle} cycles, joint speed over the last 0.5 s {mean:.3f} rad/s")


# --- Real time -----------------------------------------------------------------------------------
@pytest.mark.slow
# Not in `make test`: inside the software-emulated VM the rig cannot keep its 20 ms tick when the
# machine is shared (median tick 60 ms with a second VM running), and the loop's tracking then
# depends on the load: 1.97, 2.10, 2.12 rad/s in quiet runs, 2.83 with a second VM (CI-like run).
# Run it where real time is real: a host with vcan (`-m realtime_physics`), or a real board.
@pytest.mark.realtime_physics
def test_velocity_hold_realtime(make_scenario) -> None:
    s = make_scenario(mode="realtime")
    # The loop's gains, tuned for the latency of this world as one tunes them for a real board:
    # the rig's 20 ms tick, the firmware's 10 ms cycle and their jitter put some 40 ms of
    # transport delay in the loop, where the 1 kHz gains (kp 0.1, ki 2.0) oscillate.
    s.rig.set("velocity_kp", REALTIME_KP)
    s.rig.set("velocity_ki", REALTIME_KI)
    mean = velocity_hold(s.rig, s.expect)
    t, _ = s.rig.sent("velocity_setpoint")
    dt = np.diff(t)
    print(
        f"\nreal time: {s.rig.cycle} ticks in {s.rig.t:.3f} s (period {s.rig.period_s * 1e3:g} ms), "
        f"tick interval median {np.median(dt) * 1e3:.2f} ms, max {np.max(dt) * 1e3:.1f} ms, "
        f"{s.rig.overruns} ticks missed, plant behind by {s.rig.physics_lost_s:.3f} s; "
        f"joint speed over the last 0.5 s {mean:.3f} rad/s"
    )


@pytest.mark.slow
@pytest.mark.realtime
def test_observe_and_command_realtime_without_physics(make_scenario) -> None:
    s = make_scenario(mode="realtime", physics=False)
    count = observe_and_command(s.rig, s.expect)
    print(f"\nbring-up: {count} TPDO1 in {s.rig.t:.3f} s, {s.rig.cycle} ticks")
