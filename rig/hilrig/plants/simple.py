"""A base for a board's own plant: the plant interface's bookkeeping done once, so that a plant
is its physics and nothing else.

    class FanPlant(SimplePlant):
        sensor_fields = ("tach_counts",)      # HIL inputs the node's sensor RPDO(s) carry
        actuator_fields = ("fan_pwm",)        # fields of the node's TPDOs, applied in this order
        truth_fields = ("speed_rpm",)         # attributes of the plant, SI, unit in the name

        def __init__(self, params=None, seed=0):
            super().__init__(seed)            # self.rng: the plant's seeded noise
            self.speed_rpm = 0.0

        def sense(self):
            return self.frame(tach_counts=round(self.speed_rpm / 10 + self.rng.normal(0, 1)))

        def step(self, dt_s):
            self.speed_rpm += (self.outputs["fan_pwm"] * 0.3 - self.speed_rpm) * dt_s / 0.5

`outputs` maps each actuator field to the wire value of the last cycle (0 before the first and
whenever the node sent none: the safe default of a driver whose command stream stopped);
`frame(**values)` is the frozen frame `sense` returns (faults `dataclasses.replace` it);
`truth()` is a tuple of the `truth_fields` attributes now. `truth_parameters()` is empty unless
overridden. Subclasses that need more (a safe default other than 0) override `apply`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import numpy as np

from hilrig.plants.interface import Value


class SimplePlant:
    """The plant interface (`hilrig.plants.interface.Plant`) over a subclass's attributes."""

    sensor_fields: ClassVar[tuple[str, ...]] = ()
    actuator_fields: ClassVar[tuple[str, ...]] = ()
    truth_fields: ClassVar[tuple[str, ...]] = ()
    _frame_types: ClassVar[dict[tuple[str, ...], type]] = {}

    def __init__(self, seed: int = 0) -> None:
        missing = [name for name in ("sensor_fields", "actuator_fields") if not getattr(self, name)]
        if missing:
            raise TypeError(
                f"{type(self).__name__}: set {' and '.join(missing)} (names of the board's table)"
            )
        self.rng = np.random.default_rng(seed)
        self.outputs: dict[str, Value] = dict.fromkeys(self.actuator_fields, 0)

    def frame(self, **values: Value) -> Any:
        """This cycle's sensor frame: one value per `sensor_fields` name, no other."""
        names = self.sensor_fields
        if set(values) != set(names):
            wrong = sorted(set(values) ^ set(names))
            raise TypeError(f"{type(self).__name__}.frame: expected the values of {names}, not/also {wrong}")
        frame_type = SimplePlant._frame_types.get(names)
        if frame_type is None:
            frame_type = dataclasses.make_dataclass("SensorFrame", names, frozen=True, slots=True)
            SimplePlant._frame_types[names] = frame_type
        return frame_type(**values)

    def sense(self) -> Any:
        raise NotImplementedError(
            f"{type(self).__name__}.sense: return self.frame(<one value per sensor field>)"
        )

    def step(self, dt_s: float) -> None:
        raise NotImplementedError(f"{type(self).__name__}.step: advance the physics by dt_s")

    def truth(self) -> tuple[float, ...]:
        return tuple(float(getattr(self, name)) for name in self.truth_fields)

    def truth_matrix(self, snapshots: Sequence[tuple[float, ...]]) -> np.ndarray:
        return np.array(snapshots, dtype=np.float64).reshape(-1, len(self.truth_fields))

    def truth_parameters(self) -> Mapping[str, float]:
        return {}

    def apply(self, outputs: Sequence[Value] | None) -> None:
        values = outputs if outputs is not None else [0] * len(self.actuator_fields)
        self.outputs = dict(zip(self.actuator_fields, values, strict=True))


__all__ = ["SimplePlant"]
