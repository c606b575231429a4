"""The demo joint's own FMU (build/fmu/joint.fmu, `hilrig.apps.joint_fmu` of `make build`): valid by
FMPy's checks, and as an FMU plant through its map the same sensor readings and truth as the
rig's native joint, bit for bit, when the native joint's sensors have no noise (the FMU has none:
its map would add the plant's own, a stream other than the native sensors')."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from hilrig import resources
from hilrig.apps.demo import demo_params
from hilrig.plants.joint import JointModel
from hilrig.table import BOARD_TABLE

fmpy = pytest.importorskip("fmpy")
from hilrig.plants.fmu import FmuPlant  # noqa: E402

if resources.CHECKOUT is None:
    pytest.skip("the joint's FMU is built in a checkout (make build)", allow_module_level=True)
from hilrig.apps import joint_fmu  # noqa: E402

NOISELESS = dataclasses.replace(demo_params(), thermistor_adc_noise_counts=0.0, current_sensor_noise_a=0.0)
PERIOD_S = 1e-3


@pytest.fixture(scope="module")
def fmu() -> FmuPlant:
    assert resources.JOINT_FMU_MAP.is_file(), f"no {resources.JOINT_FMU_MAP}: run `make build`"
    return FmuPlant.load(resources.JOINT_FMU_MAP, BOARD_TABLE, seed=3)


def duties(cycles: int) -> list[int]:
    """Full forward, a sine through zero, full reverse beyond the bridge's limit: every branch of
    the duty's clamp, current both ways, the encoders wrapping backwards."""
    return [
        10_000 if n < 300 else -12_000 if n > 1200 else round(8000 * math.sin(n / 60.0))
        for n in range(cycles)
    ]


def test_fmpy_finds_the_joint_fmu_valid() -> None:
    assert joint_fmu.validate(resources.JOINT_FMU) == []
    description = fmpy.read_model_description(str(resources.JOINT_FMU))
    assert description.fmiVersion == "2.0" and description.coSimulation.canGetAndSetFMUstate


def test_the_fmu_gives_the_native_joints_readings_and_truth_bit_for_bit(fmu: FmuPlant) -> None:
    native = JointModel.of(NOISELESS, seed=3)
    assert set(native.truth_fields) <= set(fmu.truth_fields)
    assert fmu.truth_parameters()["spring_stiffness_nm_per_rad"] == NOISELESS.spring_stiffness_nm_per_rad
    columns = [fmu.truth_fields.index(name) for name in native.truth_fields]
    readings_native, readings_fmu, truth_native, truth_fmu = [], [], [], []
    for duty in duties(1600):
        readings_native.append(dataclasses.astuple(native.sense()))
        readings_fmu.append(tuple(getattr(fmu.sense(), name) for name in native.sensor_fields))
        truth_native.append(native.truth())
        truth_fmu.append(fmu.truth())
        native.apply((duty,))
        fmu.apply((duty,))
        native.step(PERIOD_S)
        fmu.step(PERIOD_S)
    assert readings_fmu == readings_native
    native_matrix = native.truth_matrix(truth_native)
    fmu_matrix = fmu.truth_matrix(truth_fmu)[:, columns]
    assert np.array_equal(fmu_matrix, native_matrix), "the FMU's state is not the native joint's"
    temperature = native.truth_fields.index("winding_temperature_c")
    assert native_matrix[-1, temperature] > native_matrix[0, temperature] + 0.05, "the winding heats"
    encoder = [row[0] for row in readings_native]
    assert max(encoder) - min(encoder) > 30_000, "the motor encoder sweeps (and wraps)"


def test_a_branch_from_a_saved_state_repeats_and_another_input_diverges() -> None:
    plant = FmuPlant.load(resources.JOINT_FMU_MAP, BOARD_TABLE, seed=1)
    for _ in range(200):
        plant.apply((6000,))
        plant.step(PERIOD_S)
    saved = plant.save_state()

    def branch(duty: int) -> list[tuple[float, ...]]:
        plant.restore_state(saved)
        rows = []
        for _ in range(100):
            plant.apply((duty,))
            plant.step(PERIOD_S)
            rows.append(plant.truth())
        return rows

    first = branch(6000)
    assert branch(6000) == first
    assert branch(-6000) != first
    assert plant.time_s == pytest.approx(0.3)
