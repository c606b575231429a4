"""The C fast paths (hilrig.plants._plant) against the Python reference conversions, the
noise stream drawn in blocks, and the plant's cached state snapshot."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from hilrig.plants import (
    STATE_FIELDS,
    JointParams,
    JointPlant,
    JointState,
    RawSensors,
    SensorModel,
    current_counts,
    encoder_counts,
    ntc_resistance,
    read_sensors,
    round_half_away,
    state_matrix,
    thermistor_adc_exact,
)
from hilrig.plants.sensors import NOISE_BLOCK_READS


def reference_reading(state: JointState, params: JointParams, noise: tuple[float, float]) -> RawSensors:
    """read_sensors spelled out with the Python reference functions."""
    thermistor_noise, current_noise = noise
    ntc_ohm = ntc_resistance(state.winding_temperature_c, params.ntc_r25_ohm, params.ntc_beta_k)
    adc = thermistor_adc_exact(ntc_ohm, params.thermistor_pullup_ohm)
    adc += params.thermistor_adc_noise_counts * thermistor_noise
    current = state.current_a + params.current_sensor_noise_a * current_noise
    return RawSensors(
        motor_encoder_counts=encoder_counts(state.motor_angle_rad, params.motor_encoder_counts_per_rev),
        output_encoder_counts=encoder_counts(state.load_angle_rad, params.output_encoder_counts_per_rev),
        thermistor_adc=min(4095, max(0, round_half_away(adc))),
        motor_current_adc=current_counts(current),
    )


def a_state(**fields: float) -> JointState:
    values = {f.name: 0.0 for f in dataclasses.fields(JointState)} | {"winding_temperature_c": 25.0}
    return JointState(**(values | fields))


# --- Noise stream -----------------------------------------------------------------------
def test_standard_normal_in_blocks_is_the_same_sequence_as_two_at_a_time() -> None:
    pairs = np.random.default_rng(99)
    block = np.random.default_rng(99).standard_normal(2 * NOISE_BLOCK_READS + 6).tolist()
    drawn_in_pairs = [float(v) for _ in range(NOISE_BLOCK_READS + 3) for v in pairs.standard_normal(2)]
    assert drawn_in_pairs == block


def test_sensor_model_readings_equal_read_sensors_across_noise_blocks() -> None:
    params = JointParams(thermistor_adc_noise_counts=4.0, current_sensor_noise_a=0.3)
    plant = JointPlant(params, winding_temperature_c=70.0, current_a=1.0)
    model, rng = SensorModel(params, 5), np.random.default_rng(5)
    for cycle in range(2 * NOISE_BLOCK_READS + 10):
        state = plant.step(1e-3, 0.5 if cycle % 300 < 150 else -0.4)
        assert model.read(state) == read_sensors(state, params, rng), cycle


def test_a_shared_generator_is_never_drawn_ahead() -> None:
    params = JointParams()
    shared = np.random.default_rng(11)
    model = SensorModel(params, shared)
    state = JointPlant(params).state
    for _ in range(3):
        model.read(state)
    expected = np.random.default_rng(11)
    expected.standard_normal(6)
    assert shared.standard_normal() == expected.standard_normal()


# --- Sensor conversions: C against the Python reference --------------------------------
def test_c_readings_equal_the_python_reference_over_random_states() -> None:
    params = JointParams(
        thermistor_adc_noise_counts=2.5,
        current_sensor_noise_a=0.7,
        motor_encoder_counts_per_rev=4000,
        output_encoder_counts_per_rev=1 << 20,
    )
    draw = np.random.default_rng(2024)
    for _ in range(3000):
        state = a_state(
            motor_angle_rad=float(draw.normal(0.0, 10.0 ** draw.uniform(-3, 6))),
            load_angle_rad=float(draw.normal(0.0, 10.0 ** draw.uniform(-3, 3))),
            current_a=float(draw.normal(0.0, 10.0 ** draw.uniform(-4, 2))),  # past the I16 range too
            winding_temperature_c=float(draw.uniform(-150.0, 400.0)),  # ADC saturates at both ends
        )
        noise = (float(draw.standard_normal()), float(draw.standard_normal()))
        rng = _ScriptedNormals(noise)
        assert read_sensors(state, params, rng) == reference_reading(state, params, noise), state  # type: ignore[arg-type]


def test_c_readings_round_halves_away_from_zero_on_exact_inputs() -> None:
    params = JointParams(thermistor_adc_noise_counts=0.0, current_sensor_noise_a=0.0)
    exact_halves = [(0.0005, 1), (-0.0005, -1), (0.0025, 3), (-0.0, 0), (33.0, 32767), (-33.0, -32768)]
    for current_a, counts in exact_halves:
        raw = read_sensors(a_state(current_a=current_a), params, np.random.default_rng(0))
        assert raw.motor_current_adc == counts == current_counts(current_a), current_a


def test_c_readings_refuse_non_finite_states_like_the_python_conversions() -> None:
    params = JointParams()
    with pytest.raises(OverflowError):
        read_sensors(a_state(motor_angle_rad=math.inf), params, np.random.default_rng(0))
    with pytest.raises(ValueError):
        read_sensors(a_state(current_a=math.nan), params, np.random.default_rng(0))
    with pytest.raises(ValueError):
        current_counts(math.nan)


def test_readings_built_in_c_are_ordinary_raw_sensors_and_user_values_are_still_checked() -> None:
    raw = SensorModel(JointParams(), 1).read(JointPlant().state)
    assert type(raw) is RawSensors
    assert raw == RawSensors(**raw.as_dict())
    with pytest.raises(dataclasses.FrozenInstanceError):
        raw.thermistor_adc = 1  # type: ignore[misc]
    with pytest.raises(ValueError, match="thermistor_adc"):
        dataclasses.replace(raw, thermistor_adc=70000)


class _ScriptedNormals:
    """Stands in for a Generator whose next two normals are known."""

    def __init__(self, normals: tuple[float, float]) -> None:
        self._normals = normals

    def standard_normal(self, count: int) -> tuple[float, float]:
        assert count == 2
        return self._normals


# --- Plant ------------------------------------------------------------------------------
def test_state_is_the_snapshot_the_last_step_returned() -> None:
    plant = JointPlant()
    first = plant.state
    assert plant.state is first
    returned = plant.step(1e-3, 0.5)
    assert plant.state is returned
    assert type(returned) is JointState and returned != first
    assert returned.time_s == 1e-3 and returned.applied_duty == 0.5
    with pytest.raises(dataclasses.FrozenInstanceError):
        returned.current_a = 0.0  # type: ignore[misc]


def test_derived_quantities_of_the_initial_state() -> None:
    params = JointParams()
    plant = JointPlant(params, motor_angle_rad=5.0, load_angle_rad=0.05, motor_velocity_rad_s=10.0,
                       winding_temperature_c=75.0)  # fmt: skip
    state = plant.state
    assert state.spring_deflection_rad == 5.0 / params.gear_ratio - 0.05
    assert state.spring_torque_nm == (
        params.spring_stiffness_nm_per_rad * state.spring_deflection_rad
        + params.spring_damping_nm_s_per_rad * (10.0 / params.gear_ratio)
    )
    assert state.winding_resistance_ohm == params.winding_resistance_at(75.0)
    assert (state.time_s, state.applied_duty) == (0.0, 0.0)


def test_holding_the_motor_keeps_time_and_duty_and_zeroes_only_the_speed() -> None:
    plant = JointPlant()
    plant.step(1e-3, 0.7)
    before = plant.state
    plant.set_motor_held(True)
    after = plant.state
    assert after == dataclasses.replace(
        before, motor_velocity_rad_s=0.0,
        spring_torque_nm=after.spring_torque_nm,  # loses the motor-speed share of the damping
    )  # fmt: skip
    assert after.motor_velocity_rad_s == 0.0


def test_a_diverging_plant_raises_with_the_time_and_state() -> None:
    plant = JointPlant(JointParams(), current_a=1e200)  # copper loss overflows to inf
    with pytest.raises(FloatingPointError, match=r"diverged at t = 0\.000000 s: \("):
        plant.step(1e-3, 1.0)
    assert plant.state.time_s == 0.0  # the failed step changed nothing


def test_step_refuses_non_numbers_and_non_finite_load_torque() -> None:
    plant = JointPlant()
    with pytest.raises(TypeError):
        plant.step(1e-3, "0.5")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"load_torque_nm: expected finite, got inf"):
        plant.step(1e-3, 0.5, math.inf)
    with pytest.raises(ValueError, match=r"dt_s: expected finite > 0, got -0\.001"):
        plant.step(-1e-3, 0.5)
    assert plant.step(1e-3, 1).applied_duty == 1.0  # ints are numbers too


def test_state_matrix_reads_every_field_of_every_state_in_declaration_order() -> None:
    plant = JointPlant(JointParams.fast_thermal())
    states = [plant.state] + [plant.step(1e-3, duty) for duty in (0.5, -0.25, 1.0)]
    matrix = state_matrix(states)
    assert tuple(field.name for field in dataclasses.fields(JointState)) == STATE_FIELDS
    assert matrix.shape == (4, len(STATE_FIELDS)) and matrix.dtype == np.float64
    expected = [[getattr(state, name) for name in STATE_FIELDS] for state in states]
    assert matrix.tolist() == expected  # bit for bit: the same doubles
    assert state_matrix([]).shape == (0, len(STATE_FIELDS))
    assert state_matrix(tuple(states[:2])).tolist() == expected[:2]


def test_state_matrix_refuses_what_is_no_joint_state() -> None:
    plant = JointPlant(JointParams())
    with pytest.raises(AttributeError, match="time_s"):
        state_matrix([plant.state, 3])  # type: ignore[list-item]
    with pytest.raises(TypeError, match="list or tuple of JointState"):
        state_matrix(5)  # type: ignore[arg-type]
