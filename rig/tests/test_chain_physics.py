"""The chain of joint modules (physics/chain.py) and the coupled JointPlant it is made of.

Native and bus-free: JointPlant(external_load=True) against closed forms and against a plant
with a huge load inertia; ChainPhysics (MuJoCo) for rest, bending, torque balance, energy,
determinism and its argument checks.
"""

from __future__ import annotations

import dataclasses
import math

import pytest

from hilrig.physics import JointParams, JointPlant

# --- JointPlant with an external load --------------------------------------------------------


def test_external_load_moves_on_at_the_speed_it_was_given() -> None:
    plant = JointPlant(JointParams(), external_load=True)
    plant.set_load_motion(0.3, -1.5)
    for _ in range(4):
        state = plant.step(1e-3, 0.5)
    assert state.load_velocity_rad_s == -1.5
    assert state.load_angle_rad == pytest.approx(0.3 - 1.5 * 4e-3, abs=1e-15)
    # The motor side did move: the duty drives current and the rotor.
    assert state.current_a > 0.1
    assert state.motor_velocity_rad_s > 0.0


def test_external_load_is_the_limit_of_a_huge_load_inertia() -> None:
    """Infinite load inertia in the coefficients = a finite plant whose load barely moves."""
    params = JointParams()
    external = JointPlant(params, external_load=True)
    heavy = JointPlant(dataclasses.replace(params, load_inertia_kg_m2=1e9), load_angle_rad=0.0)
    for i in range(300):
        duty = 0.6 * math.sin(i * 0.02)
        a = external.step(1e-3, duty)
        b = heavy.step(1e-3, duty)
    assert math.isfinite(a.motor_angle_rad)
    assert a.load_angle_rad == 0.0
    assert abs(b.load_angle_rad) < 1e-9
    assert a.motor_angle_rad == pytest.approx(b.motor_angle_rad, rel=1e-6, abs=1e-9)
    assert a.current_a == pytest.approx(b.current_a, rel=1e-6, abs=1e-9)
    assert a.spring_torque_nm == pytest.approx(b.spring_torque_nm, rel=1e-6, abs=1e-9)


def test_external_load_held_still_reaches_the_stall_torque_balance() -> None:
    """Load held at an angle, constant duty: the rotor stops where the spring carries N * kt * i
    and the current is V * duty / R (no back-EMF at rest)."""
    # R independent of the heat: a rising R would keep the rotor creeping.
    params = JointParams(copper_temperature_coefficient_per_k=0.0)
    plant = JointPlant(params, external_load=True)
    load_angle_rad = 0.2
    plant.set_load_motion(load_angle_rad, 0.0)
    duty = 0.05
    # The rotor's slow pole is stiffness / back-EMF damping at the output, 50 / 6.25 = 8 /s.
    for _ in range(2500):
        state = plant.step(1e-3, duty)
    resistance_ohm = params.winding_resistance_at(state.winding_temperature_c)
    assert state.current_a == pytest.approx(params.bus_voltage_v * duty / resistance_ohm, rel=1e-6)
    stall_torque_nm = params.gear_ratio * params.torque_constant_nm_per_a * state.current_a
    assert state.spring_torque_nm == pytest.approx(stall_torque_nm, rel=1e-6)
    gearbox_output_rad = state.motor_angle_rad / params.gear_ratio
    deflection_rad = stall_torque_nm / params.spring_stiffness_nm_per_rad
    assert state.load_angle_rad == load_angle_rad
    assert gearbox_output_rad == pytest.approx(load_angle_rad + deflection_rad, rel=1e-6)


def test_set_load_motion_updates_the_spring_torque_and_keeps_the_rest() -> None:
    params = JointParams()
    plant = JointPlant(params, external_load=True, motor_angle_rad=5.0, current_a=1.0)
    before = plant.state
    after = plant.set_load_motion(0.05, 0.4)
    assert after is plant.state
    assert (after.motor_angle_rad, after.current_a, after.time_s) == (5.0, 1.0, before.time_s)
    expected_nm = params.spring_stiffness_nm_per_rad * (5.0 / params.gear_ratio - 0.05) + (
        params.spring_damping_nm_s_per_rad * (0.0 - 0.4)
    )
    assert after.spring_torque_nm == pytest.approx(expected_nm, rel=1e-12)


def test_external_load_rejects_misuse() -> None:
    with pytest.raises(ValueError, match="external_load=False"):
        JointPlant().set_load_motion(0.0, 0.0)
    coupled = JointPlant(external_load=True)
    with pytest.raises(ValueError, match="own simulator"):
        coupled.step(1e-3, 0.0, load_torque_nm=0.1)
    with pytest.raises(ValueError, match="finite"):
        coupled.set_load_motion(math.nan, 0.0)
