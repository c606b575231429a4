"""Parameters of the demo joint's physics: one frozen dataclass, SI units throughout.

Angles are in rad, temperatures in degC (differences in K), torques in N*m. Each field
name ends in its unit. Values are checked when the object is made, so a bad scenario
parameter fails at once rather than as a NaN a thousand cycles later.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

# Default thermal time constant of JointParams.fast_thermal(): long enough to separate
# it from the mechanics, short enough that a scenario sees the winding heat up in seconds.
FAST_THERMAL_TIME_CONSTANT_S = 2.0


@dataclass(frozen=True, slots=True)
class JointParams:
    """Physical constants of the series-elastic demo joint and its sensors.

    Chain: bus voltage -> duty -> DC motor winding -> rotor -> gearbox (ratio N)
    -> torsional spring -> load. The defaults describe a small joint whose winding
    heats up over minutes; `fast_thermal()` and `with_thermal_time_constant()` shrink
    the thermal mass (keeping the steady-state rise) so tests can watch it in seconds.
    Change single values with `dataclasses.replace(params, field=value)`.
    """

    # --- Supply and motor -------------------------------------------------------------
    bus_voltage_v: float = 24.0
    """Supply of the H-bridge [V]; duty 1.0 puts this voltage across the winding."""
    winding_resistance_ohm: float = 1.0
    """Terminal resistance of the winding at `winding_reference_temperature_c` [ohm]."""
    winding_reference_temperature_c: float = 25.0
    """Temperature at which `winding_resistance_ohm` is specified [degC]."""
    copper_temperature_coefficient_per_k: float = 0.00393
    """Relative rise of the winding resistance per kelvin (copper: 0.00393) [1/K]."""
    winding_inductance_h: float = 0.5e-3
    """Winding inductance [H]; with the resistance it sets the current's time constant."""
    torque_constant_nm_per_a: float = 0.05
    """Motor torque per ampere of winding current [N*m/A]."""
    back_emf_constant_v_s_per_rad: float = 0.05
    """Back-EMF per rad/s of rotor speed [V*s/rad]; equal to the torque constant for
    an ideal motor in SI units, which keeps the electromechanical power balance exact."""
    rotor_inertia_kg_m2: float = 1e-5
    """Inertia of rotor plus gearbox input stage, at the motor shaft [kg*m^2]."""
    motor_viscous_friction_nm_s_per_rad: float = 1e-6
    """Viscous loss of bearings and gearbox, referred to the motor shaft [N*m*s/rad].
    The gearbox loss is modelled as viscous (smooth, no direction switching) rather
    than as an efficiency."""

    # --- Gearbox and spring -----------------------------------------------------------
    gear_ratio: float = 50.0
    """Motor revolutions per gearbox output revolution [1]."""
    spring_stiffness_nm_per_rad: float = 50.0
    """Torsional stiffness between gearbox output and load [N*m/rad]; 0 decouples them."""
    spring_damping_nm_s_per_rad: float = 0.02
    """Material damping of the spring, on the deflection rate [N*m*s/rad]."""

    # --- Load -------------------------------------------------------------------------
    load_inertia_kg_m2: float = 0.01
    """Inertia of the load on the spring's output side [kg*m^2]."""
    load_viscous_friction_nm_s_per_rad: float = 0.01
    """Viscous friction of the load bearing [N*m*s/rad]."""
    load_coulomb_friction_nm: float = 0.05
    """Coulomb (dry) friction of the load bearing [N*m]."""
    coulomb_smoothing_velocity_rad_s: float = 0.02
    """Load speed over which Coulomb friction ramps from 0 to full (tanh) [rad/s].
    A hard sign() would chatter around zero speed and force tiny steps."""

    # --- Winding thermal model --------------------------------------------------------
    ambient_temperature_c: float = 25.0
    """Temperature of the surroundings; also the initial winding temperature [degC]."""
    winding_thermal_resistance_k_per_w: float = 3.0
    """Thermal resistance winding -> ambient [K/W]; steady rise = copper loss * this.
    math.inf makes the winding adiabatic (useful for energy bookkeeping)."""
    winding_thermal_capacity_j_per_k: float = 60.0
    """Heat capacity of the winding [J/K]; with the resistance: time constant 180 s."""

    # --- Sensors ----------------------------------------------------------------------
    motor_encoder_counts_per_rev: int = 4096
    """Motor-side encoder counts per motor revolution [1]."""
    output_encoder_counts_per_rev: int = 16384
    """Load-side encoder counts per load revolution [1]."""
    ntc_r25_ohm: float = 10_000.0
    """NTC thermistor resistance at 25 degC [ohm]."""
    ntc_beta_k: float = 3950.0
    """NTC beta constant [K]."""
    thermistor_pullup_ohm: float = 10_000.0
    """Pull-up resistor of the thermistor divider (3.3 V -- pull-up -- NTC -- GND) [ohm]."""
    thermistor_adc_noise_counts: float = 1.0
    """Standard deviation of Gaussian noise on the thermistor ADC reading [counts]."""
    current_sensor_noise_a: float = 0.02
    """Standard deviation of Gaussian noise on the motor current reading [A]."""

    def __post_init__(self) -> None:
        positive = (
            "bus_voltage_v",
            "winding_resistance_ohm",
            "winding_inductance_h",
            "rotor_inertia_kg_m2",
            "gear_ratio",
            "load_inertia_kg_m2",
            "coulomb_smoothing_velocity_rad_s",
            "winding_thermal_resistance_k_per_w",
            "winding_thermal_capacity_j_per_k",
            "ntc_r25_ohm",
            "ntc_beta_k",
            "thermistor_pullup_ohm",
        )
        non_negative = (
            "copper_temperature_coefficient_per_k",
            "torque_constant_nm_per_a",
            "back_emf_constant_v_s_per_rad",
            "motor_viscous_friction_nm_s_per_rad",
            "spring_stiffness_nm_per_rad",
            "spring_damping_nm_s_per_rad",
            "load_viscous_friction_nm_s_per_rad",
            "load_coulomb_friction_nm",
            "thermistor_adc_noise_counts",
            "current_sensor_noise_a",
        )
        for name in positive:
            value = getattr(self, name)
            if math.isnan(value) or value <= 0.0:
                raise ValueError(f"JointParams.{name}: expected > 0, got {value}")
        for name in non_negative:
            value = getattr(self, name)
            if math.isnan(value) or value < 0.0:
                raise ValueError(f"JointParams.{name}: expected >= 0, got {value}")
        # Only the thermal resistance may be infinite (an adiabatic winding).
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            if field.name != "winding_thermal_resistance_k_per_w" and math.isinf(value):
                raise ValueError(f"JointParams.{field.name}: expected finite, got {value}")
        for name in ("motor_encoder_counts_per_rev", "output_encoder_counts_per_rev"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"JointParams.{name}: expected an int >= 1, got {value!r}")

    # --- Derived quantities -----------------------------------------------------------
    def winding_resistance_at(self, temperature_c: float) -> float:
        """Winding resistance at `temperature_c` [ohm] (linear copper coefficient)."""
        rise_k = temperature_c - self.winding_reference_temperature_c
        return self.winding_resistance_ohm * (1.0 + self.copper_temperature_coefficient_per_k * rise_k)

    @property
    def electrical_time_constant_s(self) -> float:
        """L/R of the winding at the reference temperature [s]."""
        return self.winding_inductance_h / self.winding_resistance_ohm

    @property
    def thermal_time_constant_s(self) -> float:
        """R_th * C_th of the winding [s]."""
        return self.winding_thermal_resistance_k_per_w * self.winding_thermal_capacity_j_per_k

    def spring_natural_frequency_rad_s(self, *, motor_held: bool) -> float:
        """Undamped natural frequency of the spring [rad/s].

        With the motor held it is sqrt(k / J_load); with a free rotor the rotor inertia
        reflected through the gearbox (N^2 * J_rotor) moves too: sqrt(k (1/J_l + 1/(N^2 J_r))).
        """
        inverse_inertia = 1.0 / self.load_inertia_kg_m2
        if not motor_held:
            inverse_inertia += 1.0 / (self.gear_ratio**2 * self.rotor_inertia_kg_m2)
        return math.sqrt(self.spring_stiffness_nm_per_rad * inverse_inertia)

    # --- Presets for short scenarios --------------------------------------------------
    def with_thermal_time_constant(self, time_constant_s: float) -> JointParams:
        """A copy whose winding heats with `time_constant_s`, same steady-state rise.

        Only the thermal capacity changes, so temperature limits are reached at the
        same current, just sooner: scenarios can watch derating within seconds.
        """
        if not time_constant_s > 0.0 or math.isinf(time_constant_s):
            raise ValueError(f"time_constant_s: expected finite > 0, got {time_constant_s}")
        capacity = time_constant_s / self.winding_thermal_resistance_k_per_w
        return dataclasses.replace(self, winding_thermal_capacity_j_per_k=capacity)

    @classmethod
    def fast_thermal(cls, time_constant_s: float = FAST_THERMAL_TIME_CONSTANT_S) -> JointParams:
        """The default joint with a winding thermal time constant of seconds, for tests."""
        return cls().with_thermal_time_constant(time_constant_s)
