"""One scenario file, two worlds. Each scenario is a function of (rig, expect), written once:

- lockstep: the firmware in `--mode lockstep`, one cycle per SYNC, exact simulation time (and
  the tight assertions only exact time allows);
- real time: the firmware in `--mode free` with its own 100 Hz timer and the rig ticking at
  20 Hz in wall-clock time, the physics stepped by the measured time between ticks, exactly as
  the rig would stand beside a real board (in the software-emulated VM, Python cannot keep
  1 kHz: hence the longer periods, conftest.REALTIME_*_PERIOD_US);
- a real board: the same real-time tests with `--hil-interface socketcan --hil-channel can0`
  (docs/bring-up.md, "Pointing a scenario at a real board"); the rig then opens that interface and starts
  no firmware.

The real-time assertions are what wall-clock time on a loaded machine allows: averages over
long windows taken from positions (a slope, immune to when each sample was taken), limits never
crossed, no settling times and no single samples held to a band.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import FULL_MAPPING_ON_THE_IDEAL_BUS

from boardproto.cia301 import NmtState
from hilrig.engine.rig import Rig
from hilrig.expect import Expect
from hilrig.plants import JointParams
from hilrig.table import ControlMode

pytestmark = [pytest.mark.bus, FULL_MAPPING_ON_THE_IDEAL_BUS]

VELOCITY_MODE = ControlMode.VELOCITY
SETPOINT_RAD_S = 2.0
GEAR_RATIO = JointParams().gear_ratio
HOLD_S = 4.0
AVERAGE_OVER_S = 2.0
DUTY_LIMIT = 0.95
REALTIME_KP, REALTIME_KI = 0.02, 0.2


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
    """Velocity mode, 2 rad/s at the joint, for 4 s: over the last 2 s the joint turns at
    2 rad/s within 15 % on average (the slope of its position), and the duty command stays
    inside its limits all along. The average is taken from the position, not from the velocity
    samples: in real time each position reaches the firmware with the jitter of two
    unsynchronised clocks, its velocity estimate carries that jitter (seen in the VM: single
    estimates from -0.6 to 7 rad/s while the joint turned at 2), and a mean of a dozen of those
    samples was off by up to 41 %; the position's slope over 2 s is not. Returns that slope."""
    arm(rig)
    rig.set("control_mode", VELOCITY_MODE)
    rig.set("velocity_setpoint", SETPOINT_RAD_S)
    start = rig.t
    rig.run(seconds=HOLD_S)
    expect.stays_within("motor_duty_command", -DUTY_LIMIT, DUTY_LIMIT, after_s=start)
    return expect.average_rate_within(
        "output_position", target=SETPOINT_RAD_S, tolerance=0.15, after_s=rig.t - AVERAGE_OVER_S
    )


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
@pytest.mark.requirement("CTRL_01", "CTRL_04")
def test_velocity_hold_lockstep(make_scenario) -> None:
    s = make_scenario()
    mean = velocity_hold(s.rig, s.expect)
    # Exact time allows more: the average within 1 %, the tight band of test_joint on every
    # sample, and the exact cycle count.
    s.expect.average_rate_within(
        "output_position", target=SETPOINT_RAD_S, tolerance=0.01, after_s=s.rig.t - AVERAGE_OVER_S
    )
    start = s.rig.t - HOLD_S
    s.expect.settles_within(
        "motor_velocity", target=SETPOINT_RAD_S * GEAR_RATIO, tolerance=0.02, by_s=start + 0.5, after_s=start
    )
    assert s.rig.cycle == round((0.3 + HOLD_S) / s.rig.period_s)
    print(
        f"\nlockstep: {s.rig.cycle} cycles, joint speed over the last {AVERAGE_OVER_S:g} s {mean:.4f} rad/s"
    )


# --- Real time -----------------------------------------------------------------------------------
@pytest.mark.requirement("CTRL_04")
@pytest.mark.slow
@pytest.mark.realtime
def test_velocity_hold_realtime(make_scenario) -> None:
    s = make_scenario(mode="realtime")
    # The loop's gains, tuned for the latency of this world as one tunes them for a real board:
    # the rig's 50 ms tick (the plant holds each duty that long), the firmware's 10 ms cycle and
    # their jitter, where the 1 kHz gains (kp 0.1, ki 2.0) oscillate.
    s.rig.set("velocity_kp", REALTIME_KP)
    s.rig.set("velocity_ki", REALTIME_KI)
    mean = velocity_hold(s.rig, s.expect)
    t, _ = s.rig.sent("velocity_setpoint")
    dt = np.diff(t)
    print(
        f"\nreal time: {s.rig.cycle} ticks in {s.rig.t:.3f} s (period {s.rig.period_s * 1e3:g} ms), "
        f"tick interval median {np.median(dt) * 1e3:.2f} ms, max {np.max(dt) * 1e3:.1f} ms, "
        f"{s.rig.overruns} ticks missed, plant behind by {s.rig.physics_lost_s:.3f} s; "
        f"joint speed over the last {AVERAGE_OVER_S:g} s {mean:.3f} rad/s"
    )


@pytest.mark.requirement("CTRL_04")
@pytest.mark.slow
@pytest.mark.realtime
def test_observe_and_command_realtime_without_physics(make_scenario) -> None:
    s = make_scenario(mode="realtime", physics=False)
    count = observe_and_command(s.rig, s.expect)
    print(f"\nbring-up: {count} TPDO1 in {s.rig.t:.3f} s, {s.rig.cycle} ticks")
