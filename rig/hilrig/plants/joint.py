"""The demo joint as a `hilrig.plants.interface.Plant`: its `JointPlant` and its `SensorModel`.

    model = JointModel.of(JointParams.fast_thermal(), seed=1)
    frame = model.sense()             # RawSensors -> RPDO1
    model.apply((motor_duty,))        # <- TPDO1's motor_duty (I16, 10000 = full duty)
    model.step(1e-3)

The joint's own controls (a held rotor, the air around the winding) stay on the `JointPlant`
(`model.joint`); the model forwards the ones scenarios use. A module of the MuJoCo chain is a
JointModel whose `step` its chain takes (`hilrig.plants.chain.ChainPhysics.models`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from hilrig.plants import _plant
from hilrig.plants.interface import Value
from hilrig.plants.params import JointParams
from hilrig.plants.plant import (
    I16_MAX,
    I16_MIN,
    MOTOR_DUTY_FULL_SCALE,
    STATE_FIELDS,
    JointPlant,
    JointState,
    duty_from_motor_duty,
    state_matrix,
)
from hilrig.plants.sensors import RawSensors, SensorModel

ACTUATOR_FIELD = "motor_duty"
"""The joint's one actuator output (TPDO1's I16 duty)."""
SPRING_STIFFNESS = "spring_stiffness_nm_per_rad"
"""The truth parameter the trace shows beside the firmware's spring constant estimate."""
_SENSOR_FIELDS = tuple(RawSensors.__dataclass_fields__)
_TRUTH_FIELDS = STATE_FIELDS[1:]  # not its time: the history has the cycle's


class JointModel:
    """The joint's plant and sensors behind the plant interface.

    plant: the joint's physics; sensors: its sensor models (their noise stream); stepped_by:
    who steps the plant instead of `step` (a chain's mechanics: `step` then refuses, the duty
    waits in `duty` for the chain)."""

    sensor_fields = _SENSOR_FIELDS
    actuator_fields = (ACTUATOR_FIELD,)
    truth_fields = _TRUTH_FIELDS

    def __init__(self, plant: JointPlant, sensors: SensorModel, *, stepped_by: str | None = None) -> None:
        self.joint = plant
        self.sensors = sensors
        self.stepped_by = stepped_by
        self._sensor_coefficients = sensors.packed_coefficients
        self._normals = sensors.normals
        # The plant's own method: no call of this class's in between, every cycle.
        self.step = plant.step_held if stepped_by is None else self._stepped_elsewhere  # type: ignore[method-assign]

    @classmethod
    def of(cls, params: JointParams | None = None, seed: int | np.random.Generator = 0) -> JointModel:
        """A joint of its own (its load too) with `params` and a sensor noise stream of `seed`."""
        params = params if params is not None else JointParams()
        return cls(JointPlant(params), SensorModel(params, seed))

    # --- The interface ------------------------------------------------------------------
    # Every cycle of every module calls these: they read the joint's state without its
    # property's call (the plants' own package), a cost of every cycle.
    def sense(self) -> RawSensors:  # SensorModel.read without its call
        return _plant.raw_sensors(RawSensors, self._sensor_coefficients, self.joint._state, self._normals)

    def truth(self) -> JointState:
        return self.joint._state

    def truth_matrix(self, snapshots: Sequence[JointState]) -> np.ndarray:
        return state_matrix(snapshots)[:, 1:]

    def truth_parameters(self) -> Mapping[str, float]:
        return {SPRING_STIFFNESS: self.joint.params.spring_stiffness_nm_per_rad}

    def apply(self, outputs: Sequence[Value] | None) -> None:
        # Without the actuator TPDO the bridge is off, as a motor driver whose command stream
        # stopped would be.
        if outputs is None:
            self.joint.held_duty = 0.0
            return
        raw = outputs[0]
        # duty_from_motor_duty's I16 case inline (every cycle); anything else goes through it.
        if type(raw) is int and I16_MIN <= raw <= I16_MAX:
            self.joint.held_duty = raw / MOTOR_DUTY_FULL_SCALE
        else:
            self.joint.held_duty = duty_from_motor_duty(raw)  # type: ignore[arg-type]

    @property
    def duty(self) -> float:
        """The duty fraction last applied (what the next step holds)."""
        return self.joint.held_duty

    def step(self, dt_s: float) -> None:
        self.joint.step_held(dt_s)

    def _stepped_elsewhere(self, dt_s: float) -> None:
        raise RuntimeError(f"this joint is stepped by {self.stepped_by}, not on its own")

    # --- The joint's own ----------------------------------------------------------------
    @property
    def params(self) -> JointParams:
        return self.joint.params

    @property
    def state(self) -> JointState:
        return self.joint.state

    def set_ambient_temperature(self, temperature_c: float) -> None:
        self.joint.set_ambient_temperature(temperature_c)

    def set_motor_held(self, held: bool) -> None:
        self.joint.set_motor_held(held)


def joint_plant(params: JointParams | None = None, seed: int = 0) -> JointModel:
    """The plant factory of the demo board (what a project names in `hil_plant`)."""
    return JointModel.of(params, seed)


__all__ = ["ACTUATOR_FIELD", "SPRING_STIFFNESS", "JointModel", "joint_plant"]
