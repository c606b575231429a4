"""The toy lamp's hardware for hilrig's rig: a lamp whose light follows its PWM duty with a first-order
lag (the filament heats up and cools down), seen by a photodiode on a 12-bit ADC with seeded
noise. It implements `hilrig.plants.interface.Plant`; `make_plant(params, seed)` is the factory
pytest.ini names (`hil_plant = lamp_plant:make_plant`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

PWM_FULL_SCALE = 10_000
"""lamp_pwm that means 100 % duty (the table's 0.01 % unit)."""
ADC_MAX = 4095
"""Full scale of the photodiode's 12-bit ADC: full brightness."""


@dataclass(frozen=True)
class LampParams:
    """The lamp, SI units."""

    time_constant_s: float = 0.05
    """How fast the light follows the duty (the filament's thermal lag)."""
    adc_noise_counts: float = 2.0
    """Standard deviation of the photodiode ADC's noise."""


@dataclass(frozen=True, slots=True)
class PhotodiodeFrame:
    """What the photodiode gives the node this cycle, named as the table's HIL input."""

    photodiode_adc: int


@dataclass(frozen=True, slots=True)
class LampState:
    """The lamp's truth: brightness (0..1 of full) and the duty it is driven with."""

    brightness: float
    applied_duty: float


class LampPlant:
    """The lamp behind the plant interface (see the module docstring)."""

    sensor_fields = ("photodiode_adc",)
    actuator_fields = ("lamp_pwm",)
    truth_fields = ("brightness", "applied_duty")

    def __init__(self, params: LampParams | None = None, seed: int = 0) -> None:
        self.params = params if params is not None else LampParams()
        self._rng = np.random.default_rng(seed)
        self._state = LampState(0.0, 0.0)
        self._duty = 0.0

    def sense(self) -> PhotodiodeFrame:
        noisy = self._state.brightness * ADC_MAX + self._rng.normal(0.0, self.params.adc_noise_counts)
        return PhotodiodeFrame(min(ADC_MAX, max(0, round(noisy))))

    def truth(self) -> LampState:
        return self._state

    def truth_matrix(self, snapshots: Sequence[LampState]) -> np.ndarray:
        return np.array([(s.brightness, s.applied_duty) for s in snapshots], dtype=np.float64).reshape(-1, 2)

    def truth_parameters(self) -> Mapping[str, float]:
        return {"time_constant_s": self.params.time_constant_s}

    def apply(self, outputs: Sequence[float | int] | None) -> None:
        # No PWM frame: the lamp's driver switches it off.
        self._duty = 0.0 if outputs is None else min(1.0, max(0.0, outputs[0] / PWM_FULL_SCALE))

    def step(self, dt_s: float) -> None:
        # Exact solution of the first-order lag over the step, the duty held.
        decay = math.exp(-dt_s / self.params.time_constant_s)
        brightness = self._duty + (self._state.brightness - self._duty) * decay
        self._state = LampState(brightness, self._duty)


def make_plant(params: LampParams | None, seed: int) -> LampPlant:
    """The plant factory: `make_scenario(params=..., seed=...)` calls it."""
    return LampPlant(params, seed)
