"""Sensor models and their firmware-side inverses, checked against each other."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from hilrig.plants import (
    EncoderUnwrapper,
    JointParams,
    JointPlant,
    RawSensors,
    SensorModel,
    counts_to_current_a,
    counts_to_rad,
    current_counts,
    encoder_counts,
    ntc_resistance,
    ntc_temperature_c,
    read_sensors,
    thermistor_adc,
    thermistor_adc_exact,
    thermistor_adc_to_resistance,
    thermistor_adc_to_temperature_c,
    wrapped_count_delta,
)

TWO_PI = 2.0 * math.pi
NOISELESS = dict(thermistor_adc_noise_counts=0.0, current_sensor_noise_a=0.0)


def angle_of_count(count: float, counts_per_rev: int) -> float:
    return count * TWO_PI / counts_per_rev


# --- Encoders ---------------------------------------------------------------------------
def test_encoder_quantizes_to_the_count_below_the_angle() -> None:
    assert encoder_counts(0.0, 4096) == 0
    assert encoder_counts(angle_of_count(10.5, 4096), 4096) == 10
    assert encoder_counts(angle_of_count(10.999, 4096), 4096) == 10
    assert encoder_counts(angle_of_count(11.001, 4096), 4096) == 11
    assert encoder_counts(math.pi, 4096) == 2048
    assert encoder_counts(math.pi, 16384) == 8192


def test_encoder_wraps_at_65536_in_both_directions() -> None:
    cpr = 4096
    assert encoder_counts(angle_of_count(65535.5, cpr), cpr) == 65535
    assert encoder_counts(angle_of_count(65536.5, cpr), cpr) == 0
    assert encoder_counts(angle_of_count(65536 * 3 + 7.5, cpr), cpr) == 7
    assert encoder_counts(angle_of_count(-0.5, cpr), cpr) == 65535
    assert encoder_counts(angle_of_count(-65536.5, cpr), cpr) == 65535


def test_wrapped_count_delta_takes_the_short_way_round() -> None:
    assert wrapped_count_delta(65530, 5) == 11
    assert wrapped_count_delta(5, 65530) == -11
    assert wrapped_count_delta(100, 100) == 0
    assert wrapped_count_delta(0, 32767) == 32767
    assert wrapped_count_delta(0, 32768) == -32768


def test_unwrapper_recovers_the_angle_through_many_wraps_within_one_count() -> None:
    cpr = 4096
    # 40 motor revolutions forward (2.5 wraps of the U16 counter), then 60 back.
    forward = np.linspace(0.0, 40 * TWO_PI, 2000)
    backward = np.linspace(40 * TWO_PI, -20 * TWO_PI, 3000)
    path = np.concatenate([forward, backward])
    unwrapper = EncoderUnwrapper()
    for angle in path:
        counts = unwrapper.update(encoder_counts(float(angle), cpr))
        error = float(angle) - counts_to_rad(counts, cpr)
        assert 0.0 <= error < TWO_PI / cpr + 1e-12, angle
    assert unwrapper.counts == -20 * cpr


def test_unwrapper_reads_a_first_value_near_65536_as_slightly_negative() -> None:
    unwrapper = EncoderUnwrapper()
    assert unwrapper.update(65535) == -1
    assert unwrapper.update(2) == 2
    with pytest.raises(ValueError, match="U16"):
        unwrapper.update(65536)


# --- Thermistor -------------------------------------------------------------------------
def test_ntc_follows_the_beta_curve_at_table_points() -> None:
    # Beta model of a 10 kohm, B = 3950 K NTC, worked out by hand.
    assert ntc_resistance(25.0, 10_000.0, 3950.0) == pytest.approx(10_000.0)
    assert ntc_resistance(0.0, 10_000.0, 3950.0) == pytest.approx(33_620.0, rel=1e-3)
    assert ntc_resistance(100.0, 10_000.0, 3950.0) == pytest.approx(697.6, rel=1e-3)


def test_thermistor_divider_hits_its_end_points_and_midpoint() -> None:
    assert thermistor_adc(10_000.0) == 2048  # 2047.5 rounds half away from zero
    assert thermistor_adc(0.0) == 0
    assert thermistor_adc(1e12) == 4095
    assert thermistor_adc(30_000.0, pullup_ohm=10_000.0) == round(4095 * 0.75)


def test_temperature_round_trip_error_is_within_half_an_adc_count() -> None:
    params = JointParams()
    for temperature_c in np.arange(-20.0, 150.0, 0.37):
        ntc = ntc_resistance(float(temperature_c), params.ntc_r25_ohm, params.ntc_beta_k)
        adc = thermistor_adc(ntc, params.thermistor_pullup_ohm)
        back_c = thermistor_adc_to_temperature_c(adc, params)
        # Local slope in degC per count bounds what rounding can cost.
        exact = thermistor_adc_exact(ntc, params.thermistor_pullup_ohm)
        hotter = thermistor_adc_exact(
            ntc_resistance(float(temperature_c) + 0.01, params.ntc_r25_ohm, params.ntc_beta_k),
            params.thermistor_pullup_ohm,
        )
        kelvin_per_count = 0.01 / abs(hotter - exact)
        assert abs(back_c - temperature_c) <= 0.55 * kelvin_per_count, temperature_c
        assert kelvin_per_count < 0.6  # 12 bits resolve -20..150 degC to better than 1 K


def test_resistance_and_temperature_inverses_are_exact_without_rounding() -> None:
    for ohm in (150.0, 2_000.0, 10_000.0, 90_000.0):
        temperature = ntc_temperature_c(ohm, 10_000.0, 3950.0)
        assert ntc_resistance(temperature, 10_000.0, 3950.0) == pytest.approx(ohm, rel=1e-12)
    for adc in (1, 100, 2048, 4094):
        ohm = thermistor_adc_to_resistance(adc)
        assert thermistor_adc(ohm) == adc


@pytest.mark.parametrize("adc", [0, 4095, 5000, -1])
def test_shorted_open_or_impossible_thermistor_readings_are_refused(adc: int) -> None:
    with pytest.raises(ValueError, match=f"got {adc}"):
        thermistor_adc_to_resistance(adc)


# --- Current sensor ---------------------------------------------------------------------
def test_current_counts_are_milliamps_rounded_and_saturated_to_i16() -> None:
    assert current_counts(1.234) == 1234
    assert current_counts(-1.234) == -1234
    assert current_counts(0.0005) == 1
    assert current_counts(-0.0005) == -1
    assert current_counts(0.0004) == 0
    assert current_counts(40.0) == 32767
    assert current_counts(-40.0) == -32768
    assert counts_to_current_a(current_counts(-12.345)) == pytest.approx(-12.345)


# --- Raw frame and noise ----------------------------------------------------------------
def test_raw_sensors_accept_anything_the_wire_type_holds_and_nothing_more() -> None:
    raw = RawSensors(65535, 0, 4095, -32768)
    assert raw.as_dict() == {
        "motor_encoder_counts": 65535,
        "output_encoder_counts": 0,
        "thermistor_adc": 4095,
        "motor_current_adc": -32768,
    }
    # Beyond 12 bits but inside U16: injectable as an out-of-range fault.
    assert dataclasses.replace(raw, thermistor_adc=5000).thermistor_adc == 5000
    with pytest.raises(ValueError, match=r"motor_encoder_counts: expected 0\.\.65535, got 65536"):
        dataclasses.replace(raw, motor_encoder_counts=65536)
    with pytest.raises(ValueError, match="motor_current_adc"):
        dataclasses.replace(raw, motor_current_adc=32768)
    with pytest.raises(TypeError, match="thermistor_adc"):
        dataclasses.replace(raw, thermistor_adc=12.0)  # type: ignore[arg-type]
    # Built unchecked (values in range by construction): the same reading, equal and frozen.
    unchecked = RawSensors.in_range(65535, 0, 4095, -32768)
    assert unchecked == raw and hash(unchecked) == hash(raw)
    with pytest.raises(dataclasses.FrozenInstanceError):
        unchecked.thermistor_adc = 1  # type: ignore[misc]


def test_noiseless_reading_equals_the_ideal_conversions() -> None:
    params = JointParams(**NOISELESS)
    plant = JointPlant(params, motor_angle_rad=7.3, load_angle_rad=-0.2,
                       current_a=3.2109, winding_temperature_c=61.0)  # fmt: skip
    state = plant.state

    raw = read_sensors(state, params, np.random.default_rng(0))

    assert raw == RawSensors(
        motor_encoder_counts=encoder_counts(7.3, 4096),
        output_encoder_counts=encoder_counts(-0.2, 16384),
        thermistor_adc=thermistor_adc(ntc_resistance(61.0, 10_000.0, 3950.0)),
        motor_current_adc=3211,
    )
    assert raw.output_encoder_counts > 60000  # negative angle wrapped


def test_adc_noise_has_the_configured_spread_and_no_bias() -> None:
    params = JointParams(thermistor_adc_noise_counts=3.0, current_sensor_noise_a=0.05)
    state = JointPlant(params, current_a=2.0, winding_temperature_c=40.0).state
    model = SensorModel(params, seed=42)

    readings = [model.read(state) for _ in range(4000)]

    thermistor = np.array([r.thermistor_adc for r in readings], dtype=float)
    current = np.array([r.motor_current_adc for r in readings], dtype=float)
    ideal_adc = thermistor_adc_exact(ntc_resistance(40.0, 10_000.0, 3950.0))
    assert thermistor.mean() == pytest.approx(ideal_adc, abs=0.2)
    assert thermistor.std() == pytest.approx(3.0, rel=0.1)  # plus 1/12 count^2 of rounding
    assert current.mean() == pytest.approx(2000.0, abs=3.0)
    assert current.std() == pytest.approx(50.0, rel=0.1)
    # Encoders carry no noise: only quantization.
    assert {r.motor_encoder_counts for r in readings} == {0}


def test_same_seed_gives_the_same_readings_and_another_seed_does_not() -> None:
    params = JointParams()

    def readings(seed: int) -> list[RawSensors]:
        plant = JointPlant(params)
        model = SensorModel(params, seed)
        return [model.read(plant.step(1e-3, 0.4)) for _ in range(200)]

    first, again, other = readings(7), readings(7), readings(8)
    assert first == again
    assert first != other
    # Only the noisy channels differ between seeds; the encoders agree exactly.
    assert [r.motor_encoder_counts for r in first] == [r.motor_encoder_counts for r in other]


def test_firmware_side_inverses_recover_the_plant_state_from_raw_readings() -> None:
    params = JointParams.fast_thermal(0.5)
    plant = JointPlant(params)
    model = SensorModel(params, seed=3)
    motor_unwrapper, output_unwrapper = EncoderUnwrapper(), EncoderUnwrapper()
    motor_step_rad = TWO_PI / params.motor_encoder_counts_per_rev
    output_step_rad = TWO_PI / params.output_encoder_counts_per_rev

    most_positive_rad = 0.0
    for cycle in range(3000):
        state = plant.step(1e-3, 0.8 if cycle < 1000 else -0.8)
        raw = model.read(state)
        motor_rad = counts_to_rad(
            motor_unwrapper.update(raw.motor_encoder_counts), params.motor_encoder_counts_per_rev
        )
        output_rad = counts_to_rad(
            output_unwrapper.update(raw.output_encoder_counts),
            params.output_encoder_counts_per_rev,
        )
        assert 0.0 <= state.motor_angle_rad - motor_rad < motor_step_rad + 1e-9
        assert 0.0 <= state.load_angle_rad - output_rad < output_step_rad + 1e-9
        temperature_c = thermistor_adc_to_temperature_c(raw.thermistor_adc, params)
        assert temperature_c == pytest.approx(state.winding_temperature_c, abs=0.5)
        current = counts_to_current_a(raw.motor_current_adc)
        assert current == pytest.approx(state.current_a, abs=6 * params.current_sensor_noise_a)
        most_positive_rad = max(most_positive_rad, state.motor_angle_rad)
    # The motor counter wrapped several times each way; the output's went below 0.
    wrap_rad = TWO_PI * 65536 / params.motor_encoder_counts_per_rev
    assert most_positive_rad > 3 * wrap_rad
    assert plant.state.motor_angle_rad < -3 * wrap_rad
    assert plant.state.load_angle_rad < -1.0
