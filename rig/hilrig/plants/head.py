"""The robot head module's hardware (the second board, protocol/boards/head.toml): a 6-axis IMU
on a head that nods, an RGB LED and other loads on a switched power rail, a 3-cell Li-ion
battery. It implements the plant interface (`hilrig.plants.interface`): `sense()` gives the HIL
inputs of the head's sensor RPDOs, `apply()` takes its actuator TPDO (the LED's PWM values and
the rail switch), `step(dt)` advances the battery's charge and the nod.

Physics, deliberately small and exact in simulation time:
- pose: pitch = nod_amplitude * sin(2 pi nod_hz t) plus a fixed roll; the IMU reads gravity's
  specific force in the head's frame (x forward, y left, z up) and the pitch rate on y. Mounted
  on a body (`mount_on`: a robot's head link in MuJoCo), the pose is that body's instead, and the
  IMU reads its gravity direction and its angular rate (from the orientation's change per step);
- rail: closed by the rail switch output; it draws base_load + extra_load + each LED channel's
  full current times its PWM share; the board itself draws quiescent current always;
- battery: open-circuit voltage linear in the state of charge between the cells' empty and full
  voltages, minus the internal resistance's drop; the charge falls by the current drawn.
Sensor noise (Gaussian, from the plant's own seeded generator) on every reading; ADC counts
round half away from zero as the firmware's lround does and saturate at their register's range.

The counts' scales are the table's defaults of `accel_scale` and `gyro_scale`
(`HeadParams.from_table`), so the plant and the firmware read one number.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from boardproto import BoardTable

STANDARD_GRAVITY_MPS2 = 9.80665
MILLI_PER_UNIT = 1000
"""The rail shunt ADC counts mA, the battery divider ADC mV (head.toml's HIL inputs)."""
SECONDS_PER_HOUR = 3600.0
PWM_FULL_SCALE = 255
"""An LED PWM compare value at full on."""

_I16_RANGE = (-32768, 32767)
_U16_RANGE = (0, 65535)


@dataclass(frozen=True, slots=True)
class HeadParams:
    """The head's hardware, SI units. Change values with `dataclasses.replace`."""

    accel_scale_mps2: float
    """Acceleration of one accelerometer count (the table's accel_scale default)."""
    gyro_scale_rad_s: float
    """Angular rate of one gyroscope count (the table's gyro_scale default)."""
    battery_cells: int = 3
    cell_full_v: float = 4.2
    cell_empty_v: float = 3.0
    battery_capacity_ah: float = 2.2
    battery_resistance_ohm: float = 0.15
    initial_state_of_charge: float = 0.8
    quiescent_current_a: float = 0.05
    """The head's own electronics, drawn from the battery whatever the rail does."""
    base_load_a: float = 0.6
    """Camera and fan on the rail while it is closed."""
    extra_load_a: float = 0.0
    """A fault load on the rail (a stalled fan, a short): what a scenario sets to trip it."""
    led_channel_full_a: float = 0.35
    """One LED colour at full PWM."""
    nod_amplitude_rad: float = 0.0
    nod_hz: float = 0.5
    roll_rad: float = 0.0
    accel_noise_mps2: float = 0.02
    gyro_noise_rad_s: float = 0.002
    current_noise_a: float = 0.003
    voltage_noise_v: float = 0.003

    @classmethod
    def from_table(cls, table: BoardTable, **values: float) -> HeadParams:
        """Parameters whose count scales are `table`'s defaults (the head's table), plus `values`."""
        return cls(
            accel_scale_mps2=table.field("accel_scale").default,
            gyro_scale_rad_s=table.field("gyro_scale").default,
            **values,  # type: ignore[arg-type]
        )

    def open_circuit_v(self, state_of_charge: float) -> float:
        soc = min(max(state_of_charge, 0.0), 1.0)
        return self.battery_cells * (self.cell_empty_v + (self.cell_full_v - self.cell_empty_v) * soc)


@dataclass(frozen=True, slots=True)
class HeadSensors:
    """One cycle's HIL inputs (head.toml's [[hil_input]] names), wire values."""

    accel_x_counts: int
    accel_y_counts: int
    accel_z_counts: int
    rail_current_adc: int
    gyro_x_counts: int
    gyro_y_counts: int
    gyro_z_counts: int
    battery_adc: int


@dataclass(frozen=True, slots=True)
class HeadTruth:
    """The head's hardware at one instant (SI, unit in the name)."""

    pitch_rad: float
    roll_rad: float
    pitch_rate_rad_s: float
    yaw_rate_rad_s: float
    rail_closed: float
    rail_current_a: float
    battery_current_a: float
    battery_voltage_v: float
    battery_state_of_charge: float
    led_red_duty: float
    led_green_duty: float
    led_blue_duty: float


TRUTH_FIELDS = tuple(field.name for field in dataclasses.fields(HeadTruth))
SENSOR_FIELDS = tuple(field.name for field in dataclasses.fields(HeadSensors))
ACTUATOR_FIELDS = ("led_red_pwm", "led_green_pwm", "led_blue_pwm", "rail_switch")


def _counts(value: float, low_high: tuple[int, int]) -> int:
    rounded = int(math.copysign(math.floor(abs(value) + 0.5), value))  # C's lround
    return min(max(rounded, low_high[0]), low_high[1])


def _rotation(quaternion: Sequence[float]) -> np.ndarray:
    """The rotation matrix of a unit quaternion (w, x, y, z)."""
    w, x, y, z = (float(v) for v in quaternion)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def _body_rate(before: np.ndarray, after: np.ndarray, dt_s: float) -> np.ndarray:
    """The angular rate in the body's frame that turns `before` into `after` in `dt_s` (the
    rotation vector of before^T after, over dt)."""
    delta = before.T @ after
    angle = math.acos(max(-1.0, min(1.0, (np.trace(delta) - 1.0) / 2.0)))
    axis = np.array([delta[2, 1] - delta[1, 2], delta[0, 2] - delta[2, 0], delta[1, 0] - delta[0, 1]])
    scale = 0.5 if angle < 1e-9 else angle / (2.0 * math.sin(angle))
    return axis * scale / dt_s


class HeadPlant:
    """The head module's hardware model (`hilrig.plants.interface.Plant`)."""

    sensor_fields = SENSOR_FIELDS
    actuator_fields = ACTUATOR_FIELDS
    truth_fields = TRUTH_FIELDS

    def __init__(self, params: HeadParams, seed: int = 0) -> None:
        self.params = params
        self._noise = np.random.default_rng(seed)
        self.t = 0.0
        self.charge_c = params.initial_state_of_charge * params.battery_capacity_ah * SECONDS_PER_HOUR
        """The battery's charge left [C]."""
        self._pwm = (0, 0, 0)
        self._rail_closed = False
        self._mount: Callable[[], Sequence[float]] | None = None
        self._rotation = np.eye(3)  # mounted: the body's frame in the world (columns x, y, z)
        self._rate = np.zeros(3)  # mounted: its angular rate in its own frame [rad/s]

    def mount_on(self, orientation: Callable[[], Sequence[float]]) -> None:
        """Ride on a body from now on: `orientation()` gives its unit quaternion (w, x, y, z) in
        a z-up world each step (a robot's head link: `lambda: chain.poses()[1][0]`)."""
        self._mount = orientation
        self._rotation = _rotation(orientation())
        self._rate = np.zeros(3)

    # --- what the hardware draws and shows now -----------------------------------------
    def _motion(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """Gravity's specific force [m/s^2] and the angular rate [rad/s] in the head's frame."""
        g = STANDARD_GRAVITY_MPS2
        if self._mount is not None:
            up = self._rotation.T @ np.array([0.0, 0.0, g])
            ax, ay, az = (float(v) for v in up)
            wx, wy, wz = (float(w) for w in self._rate)
            return (ax, ay, az), (wx, wy, wz)
        pitch, pitch_rate = self._pitch()
        roll = self.params.roll_rad
        level = g * math.cos(pitch)
        return (-g * math.sin(pitch), level * math.sin(roll), level * math.cos(roll)), (0.0, pitch_rate, 0.0)

    def _pitch(self) -> tuple[float, float]:
        p = self.params
        omega = 2.0 * math.pi * p.nod_hz
        amplitude = p.nod_amplitude_rad
        return amplitude * math.sin(omega * self.t), amplitude * omega * math.cos(omega * self.t)

    def rail_current_a(self) -> float:
        if not self._rail_closed:
            return 0.0
        p = self.params
        leds = sum(p.led_channel_full_a * pwm / PWM_FULL_SCALE for pwm in self._pwm)
        return p.base_load_a + p.extra_load_a + leds

    def battery_current_a(self) -> float:
        return self.params.quiescent_current_a + self.rail_current_a()

    def state_of_charge(self) -> float:
        return self.charge_c / (self.params.battery_capacity_ah * SECONDS_PER_HOUR)

    def battery_voltage_v(self) -> float:
        p = self.params
        return p.open_circuit_v(self.state_of_charge()) - self.battery_current_a() * p.battery_resistance_ohm

    # --- the plant interface -------------------------------------------------------------
    def sense(self) -> HeadSensors:
        p = self.params
        accel, gyro = self._motion()
        noise = self._noise.standard_normal(8)
        a = [
            _counts((v + p.accel_noise_mps2 * n) / p.accel_scale_mps2, _I16_RANGE)
            for v, n in zip(accel, noise[:3], strict=True)
        ]
        w = [
            _counts((v + p.gyro_noise_rad_s * n) / p.gyro_scale_rad_s, _I16_RANGE)
            for v, n in zip(gyro, noise[3:6], strict=True)
        ]
        current = self.rail_current_a() + p.current_noise_a * noise[6] if self._rail_closed else 0.0
        voltage = self.battery_voltage_v() + p.voltage_noise_v * noise[7]
        return HeadSensors(
            accel_x_counts=a[0],
            accel_y_counts=a[1],
            accel_z_counts=a[2],
            rail_current_adc=_counts(current * MILLI_PER_UNIT, _U16_RANGE),
            gyro_x_counts=w[0],
            gyro_y_counts=w[1],
            gyro_z_counts=w[2],
            battery_adc=_counts(voltage * MILLI_PER_UNIT, _U16_RANGE),
        )

    def truth(self) -> HeadTruth:
        (ax, ay, az), (_, pitch_rate, yaw_rate) = self._motion()
        red, green, blue = (pwm / PWM_FULL_SCALE for pwm in self._pwm)
        return HeadTruth(
            pitch_rad=math.atan2(-ax, math.hypot(ay, az)),
            roll_rad=math.atan2(ay, az),
            pitch_rate_rad_s=pitch_rate,
            yaw_rate_rad_s=yaw_rate,
            rail_closed=1.0 if self._rail_closed else 0.0,
            rail_current_a=self.rail_current_a(),
            battery_current_a=self.battery_current_a(),
            battery_voltage_v=self.battery_voltage_v(),
            battery_state_of_charge=self.state_of_charge(),
            led_red_duty=red,
            led_green_duty=green,
            led_blue_duty=blue,
        )

    def truth_matrix(self, snapshots: Sequence[HeadTruth]) -> np.ndarray:
        if not snapshots:
            return np.empty((0, len(TRUTH_FIELDS)))
        return np.array([dataclasses.astuple(s) for s in snapshots], dtype=np.float64)

    def truth_parameters(self) -> Mapping[str, float]:
        p = self.params
        return {
            "battery_empty_v": p.open_circuit_v(0.0),
            "battery_full_v": p.open_circuit_v(1.0),
            "battery_resistance_ohm": p.battery_resistance_ohm,
        }

    def apply(self, outputs: Sequence[float | int] | None) -> None:
        """The LED PWM values and the rail switch; None (no TPDO): the gate driver's pull-down
        opens the rail and the LED goes dark."""
        if outputs is None:
            self._pwm, self._rail_closed = (0, 0, 0), False
            return
        red, green, blue, rail = (int(v) for v in outputs)
        self._pwm = (red, green, blue)
        self._rail_closed = rail != 0

    def step(self, dt_s: float) -> None:
        self.charge_c = max(0.0, self.charge_c - self.battery_current_a() * dt_s)
        self.t += dt_s
        if self._mount is not None:  # the body has moved (a robot steps its chain first)
            rotation = _rotation(self._mount())
            self._rate = _body_rate(self._rotation, rotation, dt_s)
            self._rotation = rotation

    def set_extra_load(self, amperes: float) -> None:
        """A fault load on the rail from now on (a scenario's short or stalled fan)."""
        self.params = dataclasses.replace(self.params, extra_load_a=amperes)


__all__ = [
    "ACTUATOR_FIELDS",
    "SENSOR_FIELDS",
    "TRUTH_FIELDS",
    "HeadParams",
    "HeadPlant",
    "HeadSensors",
    "HeadTruth",
]
