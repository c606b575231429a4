"""The demo joint's plant: DC motor, gearbox, series-elastic spring, load, winding heat.

State (6 values): motor angle and speed, load angle and speed, winding current,
winding temperature. `JointPlant.step(dt_s, duty)` advances it; the physics itself is
the private `_derivative`.

Integrator: classic RK4 with fixed sub-steps inside each `step()`. The sub-step is
`SUBSTEP_FRACTION` of the plant's fastest time scale, taken from the electrical time
constant L/R (at the present winding temperature, since R rises when hot), the spring's
natural frequency with a free rotor, the electromechanical resonance sqrt(kt ke / (L J)),
the mechanical damping rates and the slope of the smoothed Coulomb friction. With
h*lambda <= 0.5 RK4 is far inside its stability region (|lambda h| < 2.78 on the real
axis) and its per-step error is ~1e-4 of the fastest decaying mode, so a 1 ms control
period on the default joint takes 4 sub-steps (L/R = 0.5 ms). A semi-implicit Euler
would be cheaper but only first-order accurate, and the tests compare against closed
forms tightly.

H-bridge convention: the winding sees duty * bus voltage. Duty 0 shorts the winding
(complementary PWM, both low sides on), so a spinning motor brakes through its back-EMF.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from hilrig.physics.params import JointParams

SUBSTEP_FRACTION = 0.5
"""Sub-step as a fraction of the fastest time scale (h * lambda <= this)."""

MOTOR_DUTY_FULL_SCALE = 10_000
"""Raw motor_duty (I16 from the firmware's TPDO1) that means 100 % of the bus voltage."""

_I16_MIN = -32768
_I16_MAX = 32767


def duty_from_motor_duty(motor_duty: int) -> float:
    """Duty fraction from the firmware's raw motor_duty (I16, -10000..10000 = -1..1).

    Values beyond +-10000 are converted as they are (e.g. 1.2); the plant clamps them
    to [-1, 1] like a real H-bridge would, and the rig can flag them separately.
    Raises ValueError for values an I16 cannot carry (a packing bug, not a duty).
    """
    if isinstance(motor_duty, bool) or not isinstance(motor_duty, int):
        raise TypeError(f"motor_duty: expected int, got {type(motor_duty).__name__}")
    if not _I16_MIN <= motor_duty <= _I16_MAX:
        raise ValueError(f"motor_duty: expected I16 ({_I16_MIN}..{_I16_MAX}), got {motor_duty}")
    return motor_duty / MOTOR_DUTY_FULL_SCALE


@dataclass(frozen=True, slots=True)
class JointState:
    """Read-only snapshot of the plant after a step (SI units)."""

    time_s: float
    """Simulation time [s]."""
    motor_angle_rad: float
    """Rotor angle, motor side of the gearbox [rad]."""
    motor_velocity_rad_s: float
    """Rotor speed [rad/s]."""
    load_angle_rad: float
    """Load angle, output side of the spring [rad]."""
    load_velocity_rad_s: float
    """Load speed [rad/s]."""
    current_a: float
    """Winding current [A]; positive drives the rotor in the positive direction."""
    winding_temperature_c: float
    """Winding temperature [degC]."""
    spring_deflection_rad: float
    """Gearbox output angle minus load angle, motor_angle / N - load_angle [rad]."""
    spring_torque_nm: float
    """Torque the spring applies to the load (stiffness plus damping) [N*m]."""
    winding_resistance_ohm: float
    """Winding resistance at the present temperature [ohm]."""
    applied_duty: float
    """Duty applied during the last step, after clamping to [-1, 1] [1]."""


# Indices into the integrator's state tuple.
_MOTOR_ANGLE, _MOTOR_VELOCITY, _LOAD_ANGLE, _LOAD_VELOCITY, _CURRENT, _TEMPERATURE = range(6)

_State = tuple[float, float, float, float, float, float]


class JointPlant:
    """Series-elastic joint, advanced by `step()`; inspect it through `state`.

    The motor can be held (rotor blocked, e.g. a jammed gearbox or a locked-rotor
    test): its angle and speed then stay put while current and heat still flow.
    """

    def __init__(
        self,
        params: JointParams | None = None,
        *,
        motor_angle_rad: float = 0.0,
        motor_velocity_rad_s: float = 0.0,
        load_angle_rad: float = 0.0,
        load_velocity_rad_s: float = 0.0,
        current_a: float = 0.0,
        winding_temperature_c: float | None = None,
        motor_held: bool = False,
    ) -> None:
        """Start at rest at angle 0 and ambient temperature unless told otherwise."""
        self._params = params if params is not None else JointParams()
        p = self._params
        temperature_c = p.ambient_temperature_c if winding_temperature_c is None else winding_temperature_c
        self._x: _State = (
            motor_angle_rad,
            0.0 if motor_held else motor_velocity_rad_s,
            load_angle_rad,
            load_velocity_rad_s,
            current_a,
            temperature_c,
        )
        if not all(math.isfinite(value) for value in self._x):
            raise ValueError(f"initial state: expected finite values, got {self._x}")
        self._time_s = 0.0
        self._applied_duty = 0.0
        self._motor_held = motor_held

        # Constants unpacked once: _derivative runs several times per sub-step.
        self._ratio = p.gear_ratio
        self._stiffness = p.spring_stiffness_nm_per_rad
        self._spring_damping = p.spring_damping_nm_s_per_rad
        self._inductance = p.winding_inductance_h
        self._r_ref = p.winding_resistance_ohm
        self._alpha = p.copper_temperature_coefficient_per_k
        self._t_ref = p.winding_reference_temperature_c
        self._kt = p.torque_constant_nm_per_a
        self._ke = p.back_emf_constant_v_s_per_rad
        self._rotor_inertia = p.rotor_inertia_kg_m2
        self._motor_friction = p.motor_viscous_friction_nm_s_per_rad
        self._load_inertia = p.load_inertia_kg_m2
        self._load_friction = p.load_viscous_friction_nm_s_per_rad
        self._coulomb = p.load_coulomb_friction_nm
        self._coulomb_speed = p.coulomb_smoothing_velocity_rad_s
        self._ambient = p.ambient_temperature_c
        self._thermal_conductance = 1.0 / p.winding_thermal_resistance_k_per_w
        self._thermal_capacity = p.winding_thermal_capacity_j_per_k
        self._substep_without_electrical_s = self._mechanical_substep_limit_s()

    @property
    def params(self) -> JointParams:
        return self._params

    @property
    def motor_held(self) -> bool:
        return self._motor_held

    @property
    def ambient_temperature_c(self) -> float:
        return self._ambient

    def set_ambient_temperature(self, temperature_c: float) -> None:
        """Change the air around the winding from now on (a disturbance a scenario applies:
        a hot enclosure heats the winding whatever the motor does)."""
        if not math.isfinite(temperature_c):
            raise ValueError(f"ambient temperature: expected a finite value, got {temperature_c}")
        self._ambient = temperature_c

    def set_motor_held(self, held: bool) -> None:
        """Block (True) or release (False) the rotor; blocking stops it at once."""
        self._motor_held = held
        if held:
            x = list(self._x)
            x[_MOTOR_VELOCITY] = 0.0
            self._x = (x[0], x[1], x[2], x[3], x[4], x[5])

    @property
    def state(self) -> JointState:
        """Snapshot of the present state."""
        motor_angle, motor_vel, load_angle, load_vel, current, temperature = self._x
        deflection = motor_angle / self._ratio - load_angle
        spring_torque = self._stiffness * deflection + self._spring_damping * (
            motor_vel / self._ratio - load_vel
        )
        return JointState(
            time_s=self._time_s,
            motor_angle_rad=motor_angle,
            motor_velocity_rad_s=motor_vel,
            load_angle_rad=load_angle,
            load_velocity_rad_s=load_vel,
            current_a=current,
            winding_temperature_c=temperature,
            spring_deflection_rad=deflection,
            spring_torque_nm=spring_torque,
            winding_resistance_ohm=self._resistance(temperature),
            applied_duty=self._applied_duty,
        )

    def max_substep_s(self) -> float:
        """Longest RK4 sub-step `step()` would take from the present state [s]."""
        resistance = self._resistance(self._x[_TEMPERATURE])
        electrical_s = self._inductance / resistance if resistance > 0.0 else math.inf
        return min(SUBSTEP_FRACTION * electrical_s, self._substep_without_electrical_s)

    def step(self, dt_s: float, duty: float, load_torque_nm: float = 0.0) -> JointState:
        """Advance by `dt_s` with `duty` held constant; return the new state.

        duty: fraction of the bus voltage in [-1, 1]; values outside are clamped, as an
        H-bridge cannot exceed its supply (convert the firmware's raw I16 with
        `duty_from_motor_duty`). load_torque_nm: external torque on the load, e.g. a
        scenario pushing on the joint [N*m].
        """
        if not (math.isfinite(dt_s) and dt_s > 0.0):
            raise ValueError(f"dt_s: expected finite > 0, got {dt_s}")
        if not math.isfinite(duty):
            raise ValueError(f"duty: expected a finite number in [-1, 1], got {duty}")
        if not math.isfinite(load_torque_nm):
            raise ValueError(f"load_torque_nm: expected finite, got {load_torque_nm}")
        duty = min(1.0, max(-1.0, duty))
        self._applied_duty = duty
        voltage = duty * self._params.bus_voltage_v

        substeps = max(1, math.ceil(dt_s / self.max_substep_s() - 1e-9))
        h = dt_s / substeps
        half = 0.5 * h
        sixth = h / 6.0
        f = self._derivative
        x = self._x
        for _ in range(substeps):
            # Unrolled over the six states: generator expressions cost twice the time.
            a0, a1, a2, a3, a4, a5 = x
            k1 = f(x, voltage, load_torque_nm)
            k2 = f(
                (a0 + half * k1[0], a1 + half * k1[1], a2 + half * k1[2],
                 a3 + half * k1[3], a4 + half * k1[4], a5 + half * k1[5]),
                voltage, load_torque_nm,
            )  # fmt: skip
            k3 = f(
                (a0 + half * k2[0], a1 + half * k2[1], a2 + half * k2[2],
                 a3 + half * k2[3], a4 + half * k2[4], a5 + half * k2[5]),
                voltage, load_torque_nm,
            )  # fmt: skip
            k4 = f(
                (a0 + h * k3[0], a1 + h * k3[1], a2 + h * k3[2],
                 a3 + h * k3[3], a4 + h * k3[4], a5 + h * k3[5]),
                voltage, load_torque_nm,
            )  # fmt: skip
            x = (
                a0 + sixth * (k1[0] + 2.0 * (k2[0] + k3[0]) + k4[0]),
                a1 + sixth * (k1[1] + 2.0 * (k2[1] + k3[1]) + k4[1]),
                a2 + sixth * (k1[2] + 2.0 * (k2[2] + k3[2]) + k4[2]),
                a3 + sixth * (k1[3] + 2.0 * (k2[3] + k3[3]) + k4[3]),
                a4 + sixth * (k1[4] + 2.0 * (k2[4] + k3[4]) + k4[4]),
                a5 + sixth * (k1[5] + 2.0 * (k2[5] + k3[5]) + k4[5]),
            )
        if not all(math.isfinite(value) for value in x):
            # Only reachable with parameters far outside a joint's range; fail loudly
            # instead of handing NaN encoder counts to the firmware.
            raise FloatingPointError(f"plant state diverged at t = {self._time_s:.6f} s: {x}")
        self._x = x
        self._time_s += dt_s
        return self.state

    # --- Physics ----------------------------------------------------------------------
    def _resistance(self, temperature_c: float) -> float:
        return self._r_ref * (1.0 + self._alpha * (temperature_c - self._t_ref))

    def _derivative(self, x: _State, voltage: float, load_torque: float) -> _State:
        """Time derivative of the state for winding voltage and external load torque."""
        motor_angle, motor_vel, load_angle, load_vel, current, temperature = x
        ratio = self._ratio
        resistance = self._r_ref * (1.0 + self._alpha * (temperature - self._t_ref))

        # Spring between gearbox output (motor_angle / N) and load; reaches the rotor
        # divided by N (the gearbox is lossless here, its loss is the viscous term).
        spring_torque = self._stiffness * (motor_angle / ratio - load_angle) + (
            self._spring_damping * (motor_vel / ratio - load_vel)
        )
        current_rate = (voltage - resistance * current - self._ke * motor_vel) / self._inductance
        if self._motor_held:
            motor_accel = 0.0
        else:
            motor_accel = (
                self._kt * current - self._motor_friction * motor_vel - spring_torque / ratio
            ) / self._rotor_inertia
        friction = self._load_friction * load_vel + self._coulomb * math.tanh(load_vel / self._coulomb_speed)
        load_accel = (spring_torque - friction + load_torque) / self._load_inertia
        heat_w = current * current * resistance
        temperature_rate = (
            heat_w - (temperature - self._ambient) * self._thermal_conductance
        ) / self._thermal_capacity
        return (motor_vel, motor_accel, load_vel, load_accel, current_rate, temperature_rate)

    def _mechanical_substep_limit_s(self) -> float:
        """Sub-step limit from every time scale except L/R (which moves with heat)."""
        p = self._params
        rates = [
            # Spring with a free rotor: the fastest of its modes (held rotor is slower).
            p.spring_natural_frequency_rad_s(motor_held=False),
            # Rotor exchanging energy with the winding's inductance (matters when R ~ 0).
            math.sqrt(
                p.torque_constant_nm_per_a
                * p.back_emf_constant_v_s_per_rad
                / (p.winding_inductance_h * p.rotor_inertia_kg_m2)
            ),
            # Damping rates of the rotor and load, including the spring's damper.
            (p.motor_viscous_friction_nm_s_per_rad + p.spring_damping_nm_s_per_rad / p.gear_ratio**2)
            / p.rotor_inertia_kg_m2,
            (p.load_viscous_friction_nm_s_per_rad + p.spring_damping_nm_s_per_rad) / p.load_inertia_kg_m2,
            # Slope of tanh-smoothed Coulomb friction at zero speed.
            p.load_coulomb_friction_nm / (p.coulomb_smoothing_velocity_rad_s * p.load_inertia_kg_m2),
            1.0 / p.thermal_time_constant_s,
        ]
        fastest = max(rates)
        return SUBSTEP_FRACTION / fastest if fastest > 0.0 else math.inf
