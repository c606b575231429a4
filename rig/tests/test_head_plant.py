"""The head module's plant (hilrig.plants.head) on its own: determinism, the IMU at rest and
nodding, the rail's loads, the battery's discharge and sag."""

from __future__ import annotations

import dataclasses
import math

import pytest

from boardproto import load_table
from hilrig import resources
from hilrig.plants.head import HeadParams, HeadPlant, HeadSensors
from hilrig.plants.interface import Plant

TABLE = load_table(resources.HEAD_TABLE)
DT_S = 1e-3


def params(**values: float) -> HeadParams:
    return HeadParams.from_table(TABLE, **values)


def quiet(**values: float) -> HeadParams:
    noises = ("accel_noise_mps2", "gyro_noise_rad_s", "current_noise_a", "voltage_noise_v")
    noiseless = dict.fromkeys(noises, 0.0)
    return params(**noiseless, **values)


def run(plant: HeadPlant, cycles: int, outputs: tuple[int, int, int, int] | None) -> list[HeadSensors]:
    frames = []
    for _ in range(cycles):
        frames.append(plant.sense())
        plant.apply(outputs)
        plant.step(DT_S)
    return frames


def test_is_a_plant_whose_fields_are_the_tables() -> None:
    plant = HeadPlant(params())
    assert isinstance(plant, Plant)
    assert set(plant.sensor_fields) == {io.name for io in TABLE.hil_inputs}
    assert set(plant.actuator_fields) == {io.name for io in TABLE.hil_outputs}
    assert plant.truth_matrix([plant.truth()]).shape == (1, len(plant.truth_fields))


def test_same_seed_same_frames_other_seed_other_noise() -> None:
    nodding = params(nod_amplitude_rad=0.3)
    first = run(HeadPlant(nodding, seed=7), 200, (255, 0, 0, 1))
    again = run(HeadPlant(nodding, seed=7), 200, (255, 0, 0, 1))
    other = run(HeadPlant(nodding, seed=8), 200, (255, 0, 0, 1))
    assert first == again
    assert first != other


def test_imu_at_rest_reads_one_g_up_in_counts() -> None:
    frame = HeadPlant(quiet()).sense()
    assert frame.accel_z_counts == 4096  # +-8 g range: 4096 counts per g (head.toml's accel_scale)
    assert (frame.accel_x_counts, frame.accel_y_counts) == (0, 0)
    assert (frame.gyro_x_counts, frame.gyro_y_counts, frame.gyro_z_counts) == (0, 0, 0)


def test_nod_shows_as_pitch_in_the_accelerometer_and_rate_in_the_gyro() -> None:
    plant = HeadPlant(quiet(nod_amplitude_rad=0.2, nod_hz=0.5))
    run(plant, 500, None)  # a quarter period of 2 s: pitch at its peak, nose down
    frame, truth = plant.sense(), plant.truth()
    assert truth.pitch_rad == pytest.approx(0.2)
    scale = TABLE.field("accel_scale").default
    measured = math.atan2(-frame.accel_x_counts * scale, frame.accel_z_counts * scale)
    assert measured == pytest.approx(0.2, abs=1e-3)
    assert abs(frame.gyro_y_counts) <= 1  # the rate crosses zero at the peak


def test_rail_current_follows_switch_loads_and_leds() -> None:
    plant = HeadPlant(quiet())
    run(plant, 1, (0, 0, 0, 0))
    assert plant.sense().rail_current_adc == 0
    run(plant, 1, (0, 0, 0, 1))
    assert plant.sense().rail_current_adc == 600  # mA: camera and fan
    run(plant, 1, (255, 255, 0, 1))
    assert plant.sense().rail_current_adc == 1300
    plant.set_extra_load(2.0)
    assert plant.sense().rail_current_adc == 3300


def test_battery_discharges_by_the_current_and_sags_under_load() -> None:
    plant = HeadPlant(quiet(battery_capacity_ah=0.01, initial_state_of_charge=1.0))
    idle = plant.battery_voltage_v()
    assert idle == pytest.approx(12.6 - 0.05 * 0.15)
    run(plant, 1000, (255, 255, 255, 1))
    truth = plant.truth()
    drawn_c = (0.05 + 0.6 + 3 * 0.35) * 1.0
    assert plant.charge_c == pytest.approx(36.0 - drawn_c)
    assert truth.battery_state_of_charge == pytest.approx(1.0 - drawn_c / 36.0)
    assert truth.battery_voltage_v < idle - 1.6 * 0.15  # the internal resistance's drop
    assert plant.sense().battery_adc == round(truth.battery_voltage_v * 1000)


def test_no_outputs_open_the_rail() -> None:
    plant = HeadPlant(quiet())
    run(plant, 1, (255, 0, 0, 1))
    plant.apply(None)
    truth = plant.truth()
    assert (truth.rail_closed, truth.led_red_duty) == (0.0, 0.0)


def test_params_from_table_take_the_tables_scales() -> None:
    p = params()
    assert p.accel_scale_mps2 == TABLE.field("accel_scale").default
    assert dataclasses.replace(p, battery_cells=2).open_circuit_v(1.0) == pytest.approx(8.4)


def _views(container: object) -> list[object]:
    views: list[object] = []
    for part in getattr(container, "contents", []):
        views.extend([part] if hasattr(part, "class_identifier") else _views(part))
    return views


def test_the_head_dashboard_shows_logged_paths_one_unit_per_plot() -> None:
    """dashboards/head.py against the head's table and plant: every series is one the tracer
    logs for this board (a field or HIL object, a truth quantity of the plant), one unit a plot."""
    from dashboards import blueprint
    from hilrig.observe.paths import entity_paths, plant_truth_path, truth_unit
    from hilrig.table import RigTable

    table = RigTable.load(resources.HEAD_TABLE)
    plant = HeadPlant(params())
    unit_of = {path: table.entry(name).unit for name, path in entity_paths(table).items()}
    unit_of |= {plant_truth_path(q): truth_unit(q) for q in plant.truth_fields}
    views = _views(blueprint("head", table).root_container)
    assert views
    for view in views:
        contents = view.contents if isinstance(view.contents, list) else []  # type: ignore[attr-defined]
        shown = [path for path in contents if not path.startswith("+ ")]
        assert all(path in unit_of for path in shown), [p for p in shown if p not in unit_of]
        units = {unit_of[path] for path in shown}
        assert len(units) <= 1, f"{view.name} mixes {sorted(units)}"  # type: ignore[attr-defined]


def test_mounted_on_a_turning_body_the_imu_reads_its_yaw_rate_and_tilt() -> None:
    """On a robot's head link (`mount_on`): a body yawing at 0.5 rad/s and pitched nose down
    by 0.1 rad reads that rate on the gyro's z axis and that pitch from gravity."""
    dt, rate, pitch = 1e-3, 0.5, 0.1
    angle = [0.0]

    def orientation() -> tuple[float, float, float, float]:
        # yaw about the world's z, then pitch about the body's y: q = q_yaw * q_pitch
        cy, sy = math.cos(angle[0] / 2), math.sin(angle[0] / 2)
        cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
        return (cy * cp, -sy * sp, cy * sp, sy * cp)

    plant = HeadPlant(quiet())
    plant.mount_on(orientation)
    for _ in range(10):
        angle[0] += rate * dt
        plant.step(dt)
    truth = plant.truth()
    assert truth.pitch_rad == pytest.approx(pitch, abs=1e-9)
    assert truth.yaw_rate_rad_s == pytest.approx(rate * math.cos(pitch), abs=1e-6)  # body z is tilted
    frame = plant.sense()
    gyro_scale = TABLE.field("gyro_scale").default
    assert frame.gyro_z_counts == round(rate * math.cos(pitch) / gyro_scale)
