"""The joint plant against closed-form solutions: motor, spring, heat, energy, stability."""

from __future__ import annotations

import dataclasses
import itertools
import math

import pytest

from hilrig.plants import JointParams, JointPlant, JointState, duty_from_motor_duty

CONTROL_PERIOD_S = 1e-3

FRICTIONLESS = dict(
    motor_viscous_friction_nm_s_per_rad=0.0,
    spring_damping_nm_s_per_rad=0.0,
    load_viscous_friction_nm_s_per_rad=0.0,
    load_coulomb_friction_nm=0.0,
)


def run(plant: JointPlant, duration_s: float, duty: float, dt_s: float = CONTROL_PERIOD_S,
        load_torque_nm: float = 0.0) -> list[JointState]:  # fmt: skip
    steps = round(duration_s / dt_s)
    return [plant.step(dt_s, duty, load_torque_nm) for _ in range(steps)]


def zero_crossing_times(times: list[float], values: list[float]) -> list[float]:
    """Times where `values` changes sign, linearly interpolated between samples."""
    crossings = []
    for (t0, v0), (t1, v1) in itertools.pairwise(zip(times, values, strict=True)):
        if v0 == 0.0 or (v0 < 0.0) != (v1 < 0.0):
            crossings.append(t0 + (t1 - t0) * v0 / (v0 - v1))
    return crossings


# --- Motor ------------------------------------------------------------------------------
def test_locked_rotor_current_is_first_order_with_tau_l_over_r() -> None:
    # No copper coefficient: R stays constant while the winding warms slightly.
    params = JointParams(copper_temperature_coefficient_per_k=0.0)
    plant = JointPlant(params, motor_held=True)
    duty = 0.5
    steady_a = duty * params.bus_voltage_v / params.winding_resistance_ohm
    tau_s = params.electrical_time_constant_s

    states = run(plant, 10e-3, duty, dt_s=0.1e-3)

    for state in states:
        expected_a = steady_a * (1.0 - math.exp(-state.time_s / tau_s))
        assert state.current_a == pytest.approx(expected_a, abs=1e-4 * steady_a), state.time_s
    # One time constant in: 63.2 % of the final value.
    at_tau = next(s for s in states if math.isclose(s.time_s, tau_s))
    assert at_tau.current_a / steady_a == pytest.approx(1.0 - math.exp(-1.0), abs=1e-4)
    assert states[-1].current_a == pytest.approx(steady_a, rel=1e-6)
    assert states[-1].motor_angle_rad == 0.0
    assert states[-1].motor_velocity_rad_s == 0.0


def test_free_rotor_speed_and_current_follow_the_second_order_solution() -> None:
    # Spring stiffness 0 decouples the load: a DC motor with rotor inertia only.
    params = JointParams(
        spring_stiffness_nm_per_rad=0.0,
        spring_damping_nm_s_per_rad=0.0,
        motor_viscous_friction_nm_s_per_rad=2e-5,
        copper_temperature_coefficient_per_k=0.0,
    )
    r, inductance = params.winding_resistance_ohm, params.winding_inductance_h
    kt, ke = params.torque_constant_nm_per_a, params.back_emf_constant_v_s_per_rad
    inertia, friction = params.rotor_inertia_kg_m2, params.motor_viscous_friction_nm_s_per_rad
    voltage = params.bus_voltage_v

    # s^2 + (R/L + b/J) s + (R b + kt ke) / (L J) = 0; the default motor is overdamped.
    trace = r / inductance + friction / inertia
    determinant = (r * friction + kt * ke) / (inductance * inertia)
    root = math.sqrt(trace**2 / 4.0 - determinant)
    fast, slow = -trace / 2.0 - root, -trace / 2.0 + root
    steady_speed = kt * voltage / (kt * ke + r * friction)
    stall_a = voltage / r

    def speed(t: float) -> float:
        return steady_speed * (1.0 + (fast * math.exp(slow * t) - slow * math.exp(fast * t)) / (slow - fast))

    def acceleration(t: float) -> float:
        return steady_speed * fast * slow * (math.exp(slow * t) - math.exp(fast * t)) / (slow - fast)

    plant = JointPlant(params)
    states = run(plant, 40e-3, 1.0)  # at the control period: sub-steps are automatic

    for state in states:
        t = state.time_s
        assert state.motor_velocity_rad_s == pytest.approx(speed(t), abs=1e-4 * steady_speed)
        # J w' + b w = kt i
        expected_current = (inertia * acceleration(t) + friction * speed(t)) / kt
        assert state.current_a == pytest.approx(expected_current, abs=5e-4 * stall_a), t
    # The mechanical time constant is the slow root: 63.2 % at -1/slow.
    tau_s = -1.0 / slow
    assert 3e-3 < tau_s < 5e-3
    assert states[-1].motor_velocity_rad_s == pytest.approx(steady_speed, rel=1e-3)
    assert states[-1].load_velocity_rad_s == 0.0


# --- Spring and load --------------------------------------------------------------------
def measured_period_s(plant: JointPlant, duration_s: float) -> tuple[float, int]:
    states = run(plant, duration_s, 0.0)
    crossings = zero_crossing_times([s.time_s for s in states], [s.spring_deflection_rad for s in states])
    half_periods = len(crossings) - 1
    return 2.0 * (crossings[-1] - crossings[0]) / half_periods, half_periods


def test_spring_and_load_oscillate_at_sqrt_k_over_j_with_motor_held() -> None:
    params = JointParams(**FRICTIONLESS)
    plant = JointPlant(params, motor_held=True, load_angle_rad=0.1)

    period_s, half_periods = measured_period_s(plant, 1.0)

    expected = 2.0 * math.pi / math.sqrt(params.spring_stiffness_nm_per_rad / params.load_inertia_kg_m2)
    assert half_periods >= 20
    assert period_s == pytest.approx(expected, rel=0.01)
    assert period_s == pytest.approx(
        2.0 * math.pi / params.spring_natural_frequency_rad_s(motor_held=True), rel=0.01
    )


def test_free_rotor_adds_its_reflected_inertia_n_squared_j_rotor() -> None:
    # Without torque constant the winding does not brake the rotor: a two-mass system.
    params = JointParams(**FRICTIONLESS, torque_constant_nm_per_a=0.0, back_emf_constant_v_s_per_rad=0.0)
    plant = JointPlant(params, load_angle_rad=0.1)

    period_s, _ = measured_period_s(plant, 1.0)

    reflected = params.gear_ratio**2 * params.rotor_inertia_kg_m2
    omega = math.sqrt(
        params.spring_stiffness_nm_per_rad * (1.0 / params.load_inertia_kg_m2 + 1.0 / reflected)
    )
    assert period_s == pytest.approx(2.0 * math.pi / omega, rel=0.01)
    # And clearly not the held-motor period (the gearbox's N^2 is in the model).
    held = 2.0 * math.pi / params.spring_natural_frequency_rad_s(motor_held=True)
    assert abs(period_s - held) > 0.1 * held


def test_external_load_torque_deflects_the_spring_by_torque_over_k() -> None:
    params = JointParams()
    plant = JointPlant(params, motor_held=True)

    state = run(plant, 3.0, 0.0, load_torque_nm=1.0)[-1]

    # Static balance: spring torque cancels the push (Coulomb friction is 0 at rest).
    assert state.spring_torque_nm == pytest.approx(-1.0, abs=2e-3)
    assert state.load_angle_rad == pytest.approx(1.0 / params.spring_stiffness_nm_per_rad, rel=2e-3)


def test_coulomb_friction_decelerates_the_load_linearly_and_stops_it_without_chatter() -> None:
    # Spring removed, only dry friction on the load: w(t) = w0 - (Tc / J) t until rest.
    params = JointParams(
        spring_stiffness_nm_per_rad=0.0,
        spring_damping_nm_s_per_rad=0.0,
        load_viscous_friction_nm_s_per_rad=0.0,
        load_coulomb_friction_nm=0.05,
    )
    plant = JointPlant(params, motor_held=True, load_velocity_rad_s=2.0)
    deceleration = params.load_coulomb_friction_nm / params.load_inertia_kg_m2  # 5 rad/s^2

    states = run(plant, 0.6, 0.0)

    for state in states:
        expected = 2.0 - deceleration * state.time_s
        if expected > 0.2:  # well above the tanh smoothing speed (0.02 rad/s)
            assert state.load_velocity_rad_s == pytest.approx(expected, abs=1e-3), state.time_s
    # At rest after 0.4 s, creeping at most at the smoothing speed, never reversing.
    assert min(s.load_velocity_rad_s for s in states) >= 0.0
    assert states[-1].load_velocity_rad_s < params.coulomb_smoothing_velocity_rad_s
    assert states[-1].load_angle_rad == pytest.approx(2.0**2 / (2.0 * deceleration), rel=0.01)


def test_motor_drives_the_load_through_the_gearbox_in_the_same_direction() -> None:
    plant = JointPlant(JointParams())

    state = run(plant, 2.0, 0.5)[-1]

    assert state.motor_velocity_rad_s > 100.0
    assert state.load_velocity_rad_s == pytest.approx(
        state.motor_velocity_rad_s / plant.params.gear_ratio, rel=1e-3
    )
    assert state.spring_torque_nm > 0.0  # pushing the load against its friction


# --- Heat -------------------------------------------------------------------------------
def test_winding_heats_to_p_times_r_th_with_the_thermal_time_constant() -> None:
    tau_s = 0.2
    params = JointParams(copper_temperature_coefficient_per_k=0.0).with_thermal_time_constant(tau_s)
    assert params.thermal_time_constant_s == pytest.approx(tau_s)
    plant = JointPlant(params, motor_held=True)
    duty = 0.25
    power_w = (duty * params.bus_voltage_v) ** 2 / params.winding_resistance_ohm
    rise_k = power_w * params.winding_thermal_resistance_k_per_w

    states = run(plant, 10 * tau_s, duty)

    for multiple in (1, 2, 3):
        state = next(s for s in states if math.isclose(s.time_s, multiple * tau_s))
        expected = rise_k * (1.0 - math.exp(-multiple))
        measured = state.winding_temperature_c - params.ambient_temperature_c
        assert measured == pytest.approx(expected, abs=3e-3 * rise_k), multiple
    final_rise = states[-1].winding_temperature_c - params.ambient_temperature_c
    assert final_rise == pytest.approx(rise_k * (1.0 - math.exp(-10.0)), rel=1e-3)


def test_hot_winding_has_more_resistance_and_settles_at_the_self_consistent_rise() -> None:
    params = JointParams.fast_thermal(0.2)
    plant = JointPlant(params, motor_held=True)
    voltage = 0.25 * params.bus_voltage_v
    r_th = params.winding_thermal_resistance_k_per_w

    state = run(plant, 3.0, 0.25)[-1]

    # Steady state: rise = V^2 / R(T) * R_th with R(T) from the copper coefficient.
    # Solved here by bisection, independently of the integrator.
    low, high = 0.0, voltage**2 / params.winding_resistance_ohm * r_th
    for _ in range(100):
        rise = 0.5 * (low + high)
        resistance = params.winding_resistance_at(params.ambient_temperature_c + rise)
        if voltage**2 / resistance * r_th > rise:
            low = rise
        else:
            high = rise
    measured_rise = state.winding_temperature_c - params.ambient_temperature_c
    assert measured_rise == pytest.approx(rise, rel=1e-3)
    assert state.winding_resistance_ohm == pytest.approx(
        params.winding_resistance_ohm * (1.0 + params.copper_temperature_coefficient_per_k * measured_rise)
    )
    assert state.current_a == pytest.approx(voltage / state.winding_resistance_ohm, rel=1e-6)
    assert state.winding_resistance_ohm > 1.2 * params.winding_resistance_ohm


# --- Energy -----------------------------------------------------------------------------
def stored_energy_j(state: JointState, params: JointParams) -> float:
    return (
        0.5 * params.rotor_inertia_kg_m2 * state.motor_velocity_rad_s**2
        + 0.5 * params.load_inertia_kg_m2 * state.load_velocity_rad_s**2
        + 0.5 * params.spring_stiffness_nm_per_rad * state.spring_deflection_rad**2
        + 0.5 * params.winding_inductance_h * state.current_a**2
    )


def test_undriven_frictionless_spring_and_load_keep_their_energy() -> None:
    params = JointParams(**FRICTIONLESS)
    plant = JointPlant(params, motor_held=True, load_angle_rad=0.1, load_velocity_rad_s=-2.0)
    initial = stored_energy_j(plant.state, params)

    states = run(plant, 5.0, 0.0)

    energies = [stored_energy_j(s, params) for s in states]
    assert max(abs(e - initial) for e in energies) < 1e-6 * initial
    assert min(s.load_velocity_rad_s for s in states) < -1.0  # it really moved


def test_energy_lost_to_the_winding_reappears_as_heat() -> None:
    # Free rotor, no friction, adiabatic winding, duty 0 (shorted winding): the only
    # loss is copper heat, so stored energy + C * temperature rise is constant.
    params = JointParams(**FRICTIONLESS, winding_thermal_resistance_k_per_w=math.inf,
                         winding_thermal_capacity_j_per_k=0.01)  # fmt: skip
    plant = JointPlant(params, load_angle_rad=0.1, motor_velocity_rad_s=50.0)
    start = plant.state

    def total_j(state: JointState) -> float:
        heat = params.winding_thermal_capacity_j_per_k * (
            state.winding_temperature_c - start.winding_temperature_c
        )
        return stored_energy_j(state, params) + heat

    states = run(plant, 1.0, 0.0)

    # RK4 at h * R/L = 0.5 leaves ~1e-5 of the energy unaccounted; a wrong gear or
    # kt/ke factor would leave tens of percent.
    initial = total_j(start)
    assert max(abs(total_j(s) - initial) for s in states) < 5e-5 * initial
    # Most of it did turn into heat.
    assert stored_energy_j(states[-1], params) < 0.2 * stored_energy_j(start, params)


# --- Integrator and inputs --------------------------------------------------------------
def test_ten_seconds_at_full_duty_stays_finite_and_bounded() -> None:
    params = JointParams()
    plant = JointPlant(params)

    states = run(plant, 10.0, 1.0)

    no_load_speed = params.bus_voltage_v / params.back_emf_constant_v_s_per_rad
    for state in states:
        values = dataclasses.astuple(state)
        assert all(math.isfinite(v) for v in values), state
        # The wound-up spring briefly pushes the rotor past its no-load speed (~5 %).
        assert abs(state.motor_velocity_rad_s) <= 1.25 * no_load_speed
        assert abs(state.current_a) <= params.bus_voltage_v / params.winding_resistance_ohm
    assert states[-1].time_s == pytest.approx(10.0)
    # Settled: the last second holds one speed, just below the no-load speed.
    last_second = [s.motor_velocity_rad_s for s in states[-1000:]]
    assert max(last_second) - min(last_second) < 1e-3 * no_load_speed
    assert 0.95 * no_load_speed < last_second[-1] < no_load_speed


def test_substeps_resolve_the_electrical_time_constant() -> None:
    params = JointParams()
    plant = JointPlant(params)
    assert plant.max_substep_s() == pytest.approx(0.5 * params.electrical_time_constant_s)

    # A hot winding has a larger R, hence a shorter L/R, hence shorter sub-steps.
    hot = JointPlant(params, winding_temperature_c=125.0)
    assert hot.max_substep_s() == pytest.approx(
        0.5 * params.winding_inductance_h / params.winding_resistance_at(125.0)
    )
    # One long step gives the same answer as many control periods.
    coarse = JointPlant(params, motor_held=True)
    fine = JointPlant(params, motor_held=True)
    coarse.step(20e-3, 0.3)
    run(fine, 20e-3, 0.3)
    assert coarse.state.current_a == pytest.approx(fine.state.current_a, rel=1e-6)


def test_duty_beyond_plus_minus_one_is_clamped_and_nan_is_refused() -> None:
    plant = JointPlant(JointParams(), motor_held=True)

    assert plant.step(1e-3, 1.7).applied_duty == 1.0
    assert plant.step(1e-3, -3.0).applied_duty == -1.0
    with pytest.raises(ValueError, match="duty"):
        plant.step(1e-3, math.nan)
    with pytest.raises(ValueError, match="dt_s"):
        plant.step(0.0, 0.5)


def test_raw_motor_duty_converts_at_10000_counts_full_scale() -> None:
    assert duty_from_motor_duty(10000) == 1.0
    assert duty_from_motor_duty(-5000) == -0.5
    assert duty_from_motor_duty(0) == 0.0
    assert duty_from_motor_duty(12000) == 1.2  # passed on; the plant clamps it
    with pytest.raises(ValueError, match="I16"):
        duty_from_motor_duty(40000)


def test_holding_the_motor_stops_it_and_releasing_lets_it_run() -> None:
    plant = JointPlant(JointParams())
    run(plant, 0.1, 0.5)
    assert plant.state.motor_velocity_rad_s > 50.0

    plant.set_motor_held(True)
    angle = plant.state.motor_angle_rad
    run(plant, 0.05, 0.5)
    assert plant.state.motor_velocity_rad_s == 0.0
    assert plant.state.motor_angle_rad == angle

    plant.set_motor_held(False)
    run(plant, 0.05, 0.5)
    assert plant.state.motor_velocity_rad_s > 50.0


def test_params_refuse_unphysical_values_and_presets_shrink_only_the_heat_capacity() -> None:
    with pytest.raises(ValueError, match=r"winding_inductance_h: expected > 0, got -0\.001"):
        JointParams(winding_inductance_h=-1e-3)
    with pytest.raises(ValueError, match="motor_encoder_counts_per_rev"):
        JointParams(motor_encoder_counts_per_rev=0)

    slow, fast = JointParams(), JointParams.fast_thermal()
    assert 60.0 <= slow.thermal_time_constant_s <= 1800.0  # minutes
    assert fast.thermal_time_constant_s == pytest.approx(2.0)
    assert fast.winding_thermal_resistance_k_per_w == slow.winding_thermal_resistance_k_per_w
    changed = [
        f.name for f in dataclasses.fields(JointParams) if getattr(slow, f.name) != getattr(fast, f.name)
    ]
    assert changed == ["winding_thermal_capacity_j_per_k"]


def test_a_hotter_ambient_heats_the_idle_winding_with_the_thermal_time_constant() -> None:
    params = JointParams().with_thermal_time_constant(1.0)
    plant = JointPlant(params)
    plant.set_ambient_temperature(50.0)
    for _ in range(1000):  # one time constant at 1 ms, no current
        plant.step(1e-3, 0.0)
    expected = 50.0 - 25.0 * math.exp(-1.0)
    assert plant.state.winding_temperature_c == pytest.approx(expected, abs=0.05)
    assert plant.ambient_temperature_c == 50.0
    with pytest.raises(ValueError):
        plant.set_ambient_temperature(float("nan"))
