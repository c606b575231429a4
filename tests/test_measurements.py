"""The firmware's measurements against the physics' truth, cycle by cycle: every sensor conversion
(encoder counts to radians across many wraps, the current ADC, the NTC divider and its Beta
equation over a wide temperature range) and the virtual sensors built on them (spring deflection,
joint torque, filtered velocity). A conversion constant off by a little, a wrap handled a count
late or a filter tuned differently moves a measurement out of bounds that come from the sensors'
own resolution and noise, not from a guess.

The truth of cycle n is the plant's state the rig sampled the sensor frame of cycle n from, so
the firmware's cycle-n outputs are compared with it directly.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import FULL_MAPPING_ON_THE_IDEAL_BUS

from hilrig.plants import JointParams
from hilrig.table import ControlMode

pytestmark = [pytest.mark.bus, FULL_MAPPING_ON_THE_IDEAL_BUS]

PARAMS = JointParams().with_thermal_time_constant(0.6)
OUTPUT_COUNT_RAD = 2 * math.pi / PARAMS.output_encoder_counts_per_rev
MOTOR_COUNT_RAD = 2 * math.pi / PARAMS.motor_encoder_counts_per_rev


def aligned(s, field: str, truth: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(cycles, the firmware's values, the truth at those cycles) of a TPDO field."""
    t, values = s.rig.history(field)
    truth_t, truth_values = s.rig.truth(truth)
    cycles = np.round(np.asarray(t) / s.rig.period_s).astype(int)
    truth_cycles = np.round(np.asarray(truth_t) / s.rig.period_s).astype(int)
    index = np.searchsorted(truth_cycles, cycles)
    assert np.array_equal(truth_cycles[index], cycles), f"{truth} has no value at some cycle of {field}"
    return cycles, np.asarray(values, dtype=float), np.asarray(truth_values, dtype=float)[index]


def worst(s, field: str, truth: str, *, scale: float = 1.0, after_s: float = 0.0) -> tuple[float, int]:
    cycles, measured, true = aligned(s, field, truth)
    keep = cycles * s.rig.period_s >= after_s
    error = np.abs(measured[keep] - scale * true[keep])
    at = int(np.argmax(error))
    return float(error[at]), int(cycles[keep][at])


@pytest.mark.requirement("MEAS_01")
def test_every_measurement_tracks_its_physical_truth(make_scenario) -> None:
    # Fast enough for the motor encoder to wrap many times (and the output encoder once), a hot
    # enclosure so the winding sweeps 25 -> 60+ degC through the NTC's curve.
    s = make_scenario(params=PARAMS)
    s.rig.set("control_mode", ControlMode.VELOCITY)
    s.rig.set("velocity_setpoint", 5.0)
    s.rig.plant.set_ambient_temperature(90.0)
    s.rig.run(seconds=1.6)
    _, load_angle = s.rig.truth("load_angle_rad")
    assert load_angle[-1] > 2 * math.pi, "the output should have turned more than once"
    _, winding = s.rig.truth("winding_temperature_c")
    assert winding[-1] - winding[0] > 30.0, "the winding should have swept a wide temperature range"

    bounds = {
        # field: (truth, scale, bound, why)
        "output_position": ("load_angle_rad", 1.0, 1.01 * OUTPUT_COUNT_RAD, "one output encoder count"),
        "spring_deflection": (
            "spring_deflection_rad",
            1.0,
            1.01 * (OUTPUT_COUNT_RAD + MOTOR_COUNT_RAD / PARAMS.gear_ratio),
            "one count of each encoder",
        ),
        "joint_torque": (
            "spring_deflection_rad",
            PARAMS.spring_stiffness_nm_per_rad,
            1.01
            * PARAMS.spring_stiffness_nm_per_rad
            * (OUTPUT_COUNT_RAD + MOTOR_COUNT_RAD / PARAMS.gear_ratio),
            "the nominal stiffness times the deflection's resolution",
        ),
        "motor_current": (
            "current_a",
            1.0,
            5 * PARAMS.current_sensor_noise_a + 0.02,
            "5 sigma of noise + ADC",
        ),
        "winding_temperature": ("winding_temperature_c", 1.0, 0.5, "ADC noise through the NTC curve"),
    }
    report = []
    for field, (truth, scale, bound, why) in bounds.items():
        error, cycle = worst(s, field, truth, scale=scale)
        report.append(f"{field}: worst {error:.3g} at cycle {cycle} (bound {bound:.3g}: {why})")
        assert error <= bound, report[-1]
    # The velocity is filtered: it lags in the step, and agrees once the motor runs steadily.
    error, cycle = worst(s, "motor_velocity", "motor_velocity_rad_s", after_s=1.0)
    bound = MOTOR_COUNT_RAD / s.rig.period_s  # one motor encoder count a cycle
    report.append(f"motor_velocity: worst {error:.3g} rad/s at cycle {cycle} after 1 s (bound {bound:.3g})")
    assert error <= bound, report[-1]
    print("\n" + "\n".join(report))


@pytest.mark.requirement("MEAS_02")
def test_velocity_is_the_first_order_filter_of_the_encoder_steps(make_scenario) -> None:
    # The firmware's motor_velocity, from the counts the rig sent: each cycle's step of the
    # 16-bit counter (modular) over one period, through a first-order low-pass at
    # velocity_filter_hz (set to 37 Hz, not the default 100, so another cut-off or no filter
    # gives other values from the first cycle of the step on).
    cutoff_hz = 37.0
    s = make_scenario()
    s.rig.set("velocity_filter_hz", cutoff_hz)
    s.rig.set("control_mode", ControlMode.VELOCITY)
    s.rig.set("velocity_setpoint", 3.0)
    s.rig.run(seconds=0.3)
    sent_t, counts = s.rig.sent("motor_encoder_counts")
    got_t, velocity = s.rig.history("motor_velocity")
    period = s.rig.period_s
    sent_cycles = np.round(np.asarray(sent_t) / period).astype(int)
    got = dict(zip(np.round(np.asarray(got_t) / period).astype(int), velocity, strict=True))
    alpha = np.float32(1.0) - np.exp(np.float32(-2.0 * math.pi * cutoff_hz * period), dtype=np.float32)
    filtered = np.float32(0.0)
    compared = 0
    for (n0, c0), (n1, c1) in zip(
        zip(sent_cycles, counts, strict=True), zip(sent_cycles[1:], counts[1:], strict=True), strict=False
    ):
        step = (int(c1) - int(c0) + 0x8000) % 0x10000 - 0x8000
        raw = np.float32(step * MOTOR_COUNT_RAD) / np.float32((n1 - n0) * period)
        filtered = filtered + alpha * (raw - filtered)
        if n1 in got:
            assert got[n1] == pytest.approx(float(filtered), rel=1e-4, abs=1e-3), (
                f"motor_velocity at cycle {n1}: a first-order filter at {cutoff_hz} Hz of the steps gives "
                f"{float(filtered):.4f} rad/s"
            )
            compared += 1
    assert compared > 250 and max(abs(v) for v in velocity) > 100.0, "the step was seen and compared"
