"""The fan board's hardware for the rig: a fan whose speed follows its PWM duty with a first-order
lag, read by a tach with seeded noise, and the air it cools, read by a thermistor ADC.
"""

from __future__ import annotations

import math

from hilrig.plants.simple import SimplePlant

PWM_FULL_SCALE = 10_000  # fan_pwm at 100 % duty (the table's 0.01 % unit)
MAX_RPM = 3000.0  # the fan's speed at full duty
DEGREES_PER_COUNT = 0.05  # the thermistor ADC's scale


class FanPlant(SimplePlant):
    sensor_fields = ("tach_rpm", "thermistor_adc")
    actuator_fields = ("fan_pwm",)
    truth_fields = ("speed_rpm", "air_c")

    def __init__(self, seed: int = 0, heat_c: float = 30.0) -> None:
        super().__init__(seed)
        self.heat_c = heat_c  # how far above 25 degC a still fan lets the air get
        self.speed_rpm, self.air_c = 0.0, 25.0 + heat_c

    def sense(self) -> object:
        tach = round(self.speed_rpm + self.rng.normal(0.0, 5.0))
        return self.frame(tach_rpm=max(0, tach), thermistor_adc=round(self.air_c / DEGREES_PER_COUNT))

    def step(self, dt_s: float) -> None:
        duty = min(1.0, max(0.0, self.outputs["fan_pwm"] / PWM_FULL_SCALE))
        self.speed_rpm = duty * MAX_RPM + (self.speed_rpm - duty * MAX_RPM) * math.exp(-dt_s / 0.2)
        still_air = 25.0 + self.heat_c * (1.0 - self.speed_rpm / MAX_RPM)
        self.air_c = still_air + (self.air_c - still_air) * math.exp(-dt_s / 0.5)


def make_plant(params: dict[str, float] | None, seed: int) -> FanPlant:
    """The factory pytest.ini names: `make_scenario(params=..., seed=...)` calls it."""
    return FanPlant(seed, **(params or {}))
