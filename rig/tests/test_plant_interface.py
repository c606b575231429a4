"""The plant interface (`hilrig.plants.interface.Plant`): the joint and the soak's pattern implement
it, the joint model is the joint's plant and sensors unchanged, and the engine, the session's
builder and the tracer know plants by that interface only (checked from their imports)."""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path

import numpy as np
import pytest

from hilrig.plants import (
    STATE_FIELDS,
    JointParams,
    JointPlant,
    RawSensors,
    SensorModel,
    default_plant,
    duty_from_motor_duty,
    state_matrix,
)
from hilrig.plants.interface import Plant
from hilrig.plants.joint import ACTUATOR_FIELD, SPRING_STIFFNESS, JointModel
from hilrig.plants.sensors import read_sensors
from hilrig.table import BOARD_TABLE

RIG = Path(__file__).resolve().parents[1] / "hilrig"
PARAMS = JointParams.fast_thermal()


def test_the_joint_model_is_a_plant_whose_fields_are_the_boards_hil_io() -> None:
    model = default_plant(PARAMS, 3)
    assert isinstance(model, Plant) and isinstance(model, JointModel)
    assert set(model.sensor_fields) == {io.name for io in BOARD_TABLE.hil_inputs}
    assert model.actuator_fields == (ACTUATOR_FIELD,)
    assert model.truth_fields == STATE_FIELDS[1:]
    assert model.truth_parameters() == {SPRING_STIFFNESS: PARAMS.spring_stiffness_nm_per_rad}


def test_a_cycle_of_the_model_is_the_joint_and_its_sensors_as_before() -> None:
    model = JointModel.of(PARAMS, 7)
    plant, sensors = JointPlant(PARAMS), SensorModel(PARAMS, 7)
    for motor_duty in (2500, -4000, 10000, 0):
        frame = model.sense()
        assert isinstance(frame, RawSensors) and frame == sensors.read(plant.state)
        assert model.truth() == plant.state
        model.apply((motor_duty,))
        model.step(1e-3)
        plant.step(1e-3, duty_from_motor_duty(motor_duty))
    assert model.truth() == plant.state
    snapshots = [model.truth(), plant.state]
    assert np.array_equal(model.truth_matrix(snapshots), state_matrix(snapshots)[:, 1:])


def test_no_outputs_turn_the_bridge_off_and_a_bad_duty_is_refused() -> None:
    model = JointModel.of(PARAMS)
    model.apply((5000,))
    assert model.duty == 0.5
    model.apply(None)  # the node sent no actuator TPDO: the bridge is off
    model.step(1e-3)
    assert model.truth().applied_duty == 0.0
    with pytest.raises(ValueError, match="I16"):
        model.apply((40000,))


def test_the_models_duty_is_duty_from_motor_duty_for_every_i16_and_refuses_the_same() -> None:
    model = JointModel.of(PARAMS)
    for motor_duty in range(-32768, 32768):
        model.apply((motor_duty,))
        assert model.duty == duty_from_motor_duty(motor_duty)
    for bad, error in ((True, TypeError), (0.5, TypeError), (-32769, ValueError), (32768, ValueError)):
        with pytest.raises(error):
            duty_from_motor_duty(bad)  # type: ignore[arg-type]
        with pytest.raises(error):
            model.apply((bad,))


def test_sensors_on_a_shared_generator_draw_two_normals_a_read_as_read_sensors() -> None:
    ours, theirs = np.random.default_rng(5), np.random.default_rng(5)
    sensors, plant = SensorModel(PARAMS, ours), JointPlant(PARAMS)
    for _ in range(3):
        assert sensors.read(plant.state) == read_sensors(plant.state, PARAMS, theirs)
        assert ours.standard_normal() == theirs.standard_normal()  # never drawn ahead


def test_a_frame_is_a_frozen_dataclass_a_fault_can_replace_a_value_of() -> None:
    frame = JointModel.of(PARAMS).sense()
    assert dataclasses.replace(frame, thermistor_adc=4095).thermistor_adc == 4095


def test_a_chain_module_is_a_plant_the_chain_steps() -> None:
    pytest.importorskip("mujoco")
    from hilrig.plants.chain import ChainPhysics

    chain = ChainPhysics(2, PARAMS, seed=1)
    assert all(isinstance(model, Plant) for model in chain.models)
    assert [model.joint for model in chain.models] == list(chain.plants)
    with pytest.raises(RuntimeError, match="its chain"):
        chain.models[0].step(1e-3)
    chain.models[0].apply((10000,))
    chain.models[1].apply(None)
    chain.step(1e-3)  # each module's applied duty
    assert [model.truth().applied_duty for model in chain.models] == [1.0, 0.0]
    # Module k's sensors draw the noise of seed * 1000 + k, as a rig of that seed did.
    reference = SensorModel(PARAMS, 1001)
    assert chain.models[1].sense() == reference.read(chain.plants[1].state)


PLANT_BLIND = ("engine", "observe", "session/builder.py")
"""What knows plants by the interface only."""
MAY_NAME = frozenset({"Plant", "Value", "default_plant", "ChainPhysics", "ChainGeometry"})
"""What those may import of hilrig.plants: the interface, the default plant of a rig given none,
and a robot's chain (its mechanics, which the builder makes and the robot steps)."""


def test_the_engine_the_builder_and_the_tracer_know_only_the_interface() -> None:
    files = [
        p
        for part in PLANT_BLIND
        for p in sorted((RIG / part).rglob("*.py") if "." not in part else [RIG / part])
    ]
    named: dict[str, set[str]] = {}
    for path in files:
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("hilrig.plants"):
                named.setdefault(str(path.relative_to(RIG)), set()).update(a.name for a in node.names)
            elif isinstance(node, ast.Import):
                assert not any(a.name.startswith("hilrig.plants") for a in node.names), path
    beyond = {path: sorted(names - MAY_NAME) for path, names in named.items() if names - MAY_NAME}
    assert beyond == {}
    assert named  # the check saw the imports it is about
