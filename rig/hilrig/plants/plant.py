"""The demo joint's plant: DC motor, gearbox, series-elastic spring, load, winding heat.

State (6 values): motor angle and speed, load angle and speed, winding current,
winding temperature. `JointPlant.step(dt_s, duty)` advances it. The physics itself (the
derivative, the RK4 integrator with its sub-step rule, the H-bridge convention) lives in
the C extension `hilrig.plants._plant` (_plant.c, documented there): the rig runs in an
emulated CPU where Python's float code is slowest. This module keeps the API, the
validation of parameters and the sub-step limits that do not change during a run.
"""

from __future__ import annotations

import math
from array import array
from collections.abc import Sequence
from dataclasses import dataclass, fields

import numpy as np

from hilrig.plants import _plant
from hilrig.plants.params import JointParams

SUBSTEP_FRACTION = 0.5
"""Sub-step as a fraction of the fastest time scale (h * lambda <= this)."""

MOTOR_DUTY_FULL_SCALE = 10_000
"""Raw motor_duty (I16 from the firmware's TPDO1) that means 100 % of the bus voltage."""

I16_MIN = -32768
I16_MAX = 32767


def duty_from_motor_duty(motor_duty: int) -> float:
    """Duty fraction from the firmware's raw motor_duty (I16, -10000..10000 = -1..1).

    Values beyond +-10000 are converted as they are (e.g. 1.2); the plant clamps them
    to [-1, 1] like a real H-bridge would, and the rig can flag them separately.
    Raises ValueError for values an I16 cannot carry (a packing bug, not a duty).
    """
    if type(motor_duty) is not int and (isinstance(motor_duty, bool) or not isinstance(motor_duty, int)):
        raise TypeError(f"motor_duty: expected int, got {type(motor_duty).__name__}")
    if not I16_MIN <= motor_duty <= I16_MAX:
        raise ValueError(f"motor_duty: expected I16 ({I16_MIN}..{I16_MAX}), got {motor_duty}")
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


STATE_FIELDS: tuple[str, ...] = tuple(f.name for f in fields(JointState))
"""JointState's fields in declaration order: the columns of `state_matrix`."""


def state_matrix(states: Sequence[JointState]) -> np.ndarray:
    """The states as a float64 (len(states) x len(STATE_FIELDS)) array, a column per field, read
    in C (a batch of the truth in the tracer, a truth series of the History)."""
    values = np.frombuffer(_plant.state_values(states), dtype=np.float64)
    return values.reshape(len(states), len(STATE_FIELDS))


def plant_coefficients(
    params: JointParams, substep_without_electrical_s: float, *, external_load: bool = False
) -> dict[str, float]:
    """The constants _plant.c reads by name, in the order of _joint_core.h's C_* enum (all
    floats): the joint's FMU takes them as its parameters under these names.

    external_load: the load side belongs to another simulator (MuJoCo's chain). The load
    inertia becomes +inf, so _plant.c's load acceleration (finite torque) / inf is 0: over a
    step the load keeps the velocity it was given (a prescribed motion) and the same C
    arithmetic integrates the motor side. Load friction is zeroed: the other simulator owns
    it (it would be divided by inf anyway).
    """
    p = params
    load_inertia = math.inf if external_load else p.load_inertia_kg_m2
    load_viscous = 0.0 if external_load else p.load_viscous_friction_nm_s_per_rad
    load_coulomb = 0.0 if external_load else p.load_coulomb_friction_nm
    coefficients = {
        name: float(value)
        for name, value in (
            ("gear_ratio", p.gear_ratio),
            ("spring_stiffness_nm_per_rad", p.spring_stiffness_nm_per_rad),
            ("spring_damping_nm_s_per_rad", p.spring_damping_nm_s_per_rad),
            ("winding_inductance_h", p.winding_inductance_h),
            ("winding_resistance_at_reference_ohm", p.winding_resistance_ohm),  # the state has its own
            ("copper_temperature_coefficient_per_k", p.copper_temperature_coefficient_per_k),
            ("winding_reference_temperature_c", p.winding_reference_temperature_c),
            ("torque_constant_nm_per_a", p.torque_constant_nm_per_a),
            ("back_emf_constant_v_s_per_rad", p.back_emf_constant_v_s_per_rad),
            ("rotor_inertia_kg_m2", p.rotor_inertia_kg_m2),
            ("motor_viscous_friction_nm_s_per_rad", p.motor_viscous_friction_nm_s_per_rad),
            ("load_inertia_kg_m2", load_inertia),
            ("load_viscous_friction_nm_s_per_rad", load_viscous),
            ("load_coulomb_friction_nm", load_coulomb),
            ("coulomb_smoothing_velocity_rad_s", p.coulomb_smoothing_velocity_rad_s),
            (
                "winding_thermal_conductance_w_per_k",
                1.0 / p.winding_thermal_resistance_k_per_w,
            ),  # 0: adiabatic
            ("winding_thermal_capacity_j_per_k", p.winding_thermal_capacity_j_per_k),
            ("bus_voltage_v", p.bus_voltage_v),
            ("substep_fraction", SUBSTEP_FRACTION),
            ("substep_without_electrical_s", substep_without_electrical_s),
        )
    }
    assert len(coefficients) == _plant.PLANT_COEFFICIENT_COUNT
    return coefficients


def _plant_coefficients(
    params: JointParams, substep_without_electrical_s: float, *, external_load: bool = False
) -> bytes:
    """`plant_coefficients` packed as _plant.c takes them (native doubles)."""
    return array(
        "d", plant_coefficients(params, substep_without_electrical_s, external_load=external_load).values()
    ).tobytes()


class JointPlant:
    """Series-elastic joint, advanced by `step()`; inspect it through `state`.

    The motor can be held (rotor blocked, e.g. a jammed gearbox or a locked-rotor
    test): its angle and speed then stay put while current and heat still flow.
    The state is the latest JointState itself: `step()` builds the next one (in C) and
    `state` hands out that same immutable snapshot, so reading it costs nothing.

    With `external_load=True` the load side is another simulator's (a module of MuJoCo's
    chain, physics/chain.py): before each `step()` it hands over the load's angle and speed
    with `set_load_motion()`; during the step the load moves on at that constant speed
    (infinite load inertia) while the motor, spring and heat evolve as usual; the new
    state's `spring_torque_nm` is then the torque for the other simulator's joint. The
    load's inertia and friction in JointParams are not used: they are the other side's.
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
        external_load: bool = False,
    ) -> None:
        """Start at rest at angle 0 and ambient temperature unless told otherwise."""
        self._params = params if params is not None else JointParams()
        p = self._params
        temperature_c = p.ambient_temperature_c if winding_temperature_c is None else winding_temperature_c
        initial = (
            motor_angle_rad,
            0.0 if motor_held else motor_velocity_rad_s,
            load_angle_rad,
            load_velocity_rad_s,
            current_a,
            temperature_c,
        )
        if not all(math.isfinite(value) for value in initial):
            raise ValueError(f"initial state: expected finite values, got {initial}")
        self._motor_held = motor_held
        self._external_load = external_load
        self._ambient = p.ambient_temperature_c
        self._coefficients = _plant_coefficients(
            p, self._mechanical_substep_limit_s(), external_load=external_load
        )
        self._state: JointState = _plant.joint_state(JointState, self._coefficients, 0.0, *initial, 0.0)
        self.held_duty = 0.0
        """The duty `step_held` holds (a fraction of the bus voltage, clamped as in `step`)."""

    @property
    def params(self) -> JointParams:
        return self._params

    @property
    def motor_held(self) -> bool:
        return self._motor_held

    @property
    def external_load(self) -> bool:
        """True when the load side is another simulator's (see `set_load_motion`)."""
        return self._external_load

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
            s = self._state
            self._state = _plant.joint_state(
                JointState, self._coefficients, s.time_s, s.motor_angle_rad, 0.0, s.load_angle_rad,
                s.load_velocity_rad_s, s.current_a, s.winding_temperature_c, s.applied_duty,
            )  # fmt: skip

    def set_load_motion(self, load_angle_rad: float, load_velocity_rad_s: float) -> JointState:
        """Put the load where the other simulator has it (external_load plants only).

        The rest of the state stays; the derived spring deflection and torque follow the new
        load. Returns the new state. Raises ValueError for non-finite values.
        """
        if not self._external_load:
            raise ValueError("set_load_motion: this plant integrates its own load (external_load=False)")
        if not (math.isfinite(load_angle_rad) and math.isfinite(load_velocity_rad_s)):
            raise ValueError(f"load motion: expected finite, got {load_angle_rad}, {load_velocity_rad_s}")
        s = self._state
        self._state = _plant.joint_state(
            JointState, self._coefficients, s.time_s, s.motor_angle_rad, s.motor_velocity_rad_s,
            load_angle_rad, load_velocity_rad_s, s.current_a, s.winding_temperature_c, s.applied_duty,
        )  # fmt: skip
        return self._state

    @property
    def state(self) -> JointState:
        """Snapshot of the present state."""
        return self._state

    def max_substep_s(self) -> float:
        """Longest RK4 sub-step `step()` would take from the present state [s]."""
        return _plant.max_substep_s(self._coefficients, self._state.winding_temperature_c)

    def step(self, dt_s: float, duty: float, load_torque_nm: float = 0.0) -> JointState:
        """Advance by `dt_s` with `duty` held constant; return the new state.

        duty: fraction of the bus voltage in [-1, 1]; values outside are clamped, as an
        H-bridge cannot exceed its supply (convert the firmware's raw I16 with
        `duty_from_motor_duty`). load_torque_nm: external torque on the load, e.g. a
        scenario pushing on the joint [N*m]; with an external load it must be 0 (push on the
        other simulator's joint instead). Raises ValueError for non-finite inputs and
        FloatingPointError if the state diverges (parameters far outside a joint's range).
        """
        if load_torque_nm and self._external_load:
            raise ValueError("load_torque_nm: an external load takes its torques in its own simulator")
        self._state = _plant.advance(
            self._coefficients, self._state, dt_s, duty, load_torque_nm, self._motor_held, self._ambient
        )
        return self._state

    def step_held(self, dt_s: float) -> JointState:
        """`step(dt_s, held_duty)` with no load torque: a rig's every cycle, one call."""
        self._state = _plant.advance(
            self._coefficients, self._state, dt_s, self.held_duty, 0.0, self._motor_held, self._ambient
        )
        return self._state

    def _mechanical_substep_limit_s(self) -> float:
        """Sub-step limit from every time scale except L/R (which moves with heat)."""
        p = self._params
        # An external load is a prescribed motion: infinite inertia, no own friction; the
        # rates below that divide by its inertia become 0 (never inf * 0: no NaN).
        load_inertia = math.inf if self._external_load else p.load_inertia_kg_m2
        load_viscous = 0.0 if self._external_load else p.load_viscous_friction_nm_s_per_rad
        load_coulomb = 0.0 if self._external_load else p.load_coulomb_friction_nm
        if self._external_load:
            # The rotor alone on the spring against a prescribed load: sqrt(k / (N^2 J_rotor)).
            spring_rate = math.sqrt(p.spring_stiffness_nm_per_rad / (p.gear_ratio**2 * p.rotor_inertia_kg_m2))
        else:
            # Spring with a free rotor: the fastest of its modes (held rotor is slower).
            spring_rate = p.spring_natural_frequency_rad_s(motor_held=False)
        rates = [
            spring_rate,
            # Rotor exchanging energy with the winding's inductance (matters when R ~ 0).
            math.sqrt(
                p.torque_constant_nm_per_a
                * p.back_emf_constant_v_s_per_rad
                / (p.winding_inductance_h * p.rotor_inertia_kg_m2)
            ),
            # Damping rates of the rotor and load, including the spring's damper.
            (p.motor_viscous_friction_nm_s_per_rad + p.spring_damping_nm_s_per_rad / p.gear_ratio**2)
            / p.rotor_inertia_kg_m2,
            (load_viscous + p.spring_damping_nm_s_per_rad) / load_inertia,
            # Slope of tanh-smoothed Coulomb friction at zero speed.
            load_coulomb / (p.coulomb_smoothing_velocity_rad_s * load_inertia),
            1.0 / p.thermal_time_constant_s,
        ]
        fastest = max(rates)
        return SUBSTEP_FRACTION / fastest if fastest > 0.0 else math.inf


def joint_coefficients(params: JointParams) -> dict[str, float]:
    """`plant_coefficients` of a joint of its own with `params`, its sub-step limit included:
    the parameters of the joint's FMU (`hilrig.apps.joint_fmu`)."""
    return plant_coefficients(params, JointPlant(params)._mechanical_substep_limit_s())
