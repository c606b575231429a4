"""The chain of joint modules (physics/chain.py) and the coupled JointPlant it is made of.

Native and bus-free: JointPlant(external_load=True) against closed forms and against a plant
with a huge load inertia; ChainPhysics (MuJoCo) for rest, bending, torque balance, energy,
determinism and its argument checks.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from hilrig.plants import JointParams, JointPlant

# --- JointPlant with an external load --------------------------------------------------------


def test_external_load_moves_on_at_the_speed_it_was_given() -> None:
    plant = JointPlant(JointParams(), external_load=True)
    plant.set_load_motion(0.3, -1.5)
    for _ in range(4):
        state = plant.step(1e-3, 0.5)
    assert state.load_velocity_rad_s == -1.5
    assert state.load_angle_rad == pytest.approx(0.3 - 1.5 * 4e-3, abs=1e-15)
    # The motor side did move: the duty drives current and the rotor.
    assert state.current_a > 0.1
    assert state.motor_velocity_rad_s > 0.0


def test_external_load_is_the_limit_of_a_huge_load_inertia() -> None:
    """Infinite load inertia in the coefficients = a finite plant whose load barely moves."""
    params = JointParams()
    external = JointPlant(params, external_load=True)
    heavy = JointPlant(dataclasses.replace(params, load_inertia_kg_m2=1e9), load_angle_rad=0.0)
    for i in range(300):
        duty = 0.6 * math.sin(i * 0.02)
        a = external.step(1e-3, duty)
        b = heavy.step(1e-3, duty)
    assert math.isfinite(a.motor_angle_rad)
    assert a.load_angle_rad == 0.0
    assert abs(b.load_angle_rad) < 1e-9
    assert a.motor_angle_rad == pytest.approx(b.motor_angle_rad, rel=1e-6, abs=1e-9)
    assert a.current_a == pytest.approx(b.current_a, rel=1e-6, abs=1e-9)
    assert a.spring_torque_nm == pytest.approx(b.spring_torque_nm, rel=1e-6, abs=1e-9)


def test_external_load_held_still_reaches_the_stall_torque_balance() -> None:
    """Load held at an angle, constant duty: the rotor stops where the spring carries N * kt * i
    and the current is V * duty / R (no back-EMF at rest)."""
    # R independent of the heat: a rising R would keep the rotor creeping.
    params = JointParams(copper_temperature_coefficient_per_k=0.0)
    plant = JointPlant(params, external_load=True)
    load_angle_rad = 0.2
    plant.set_load_motion(load_angle_rad, 0.0)
    duty = 0.05
    # The rotor's slow pole is stiffness / back-EMF damping at the output, 50 / 6.25 = 8 /s.
    for _ in range(2500):
        state = plant.step(1e-3, duty)
    resistance_ohm = params.winding_resistance_at(state.winding_temperature_c)
    assert state.current_a == pytest.approx(params.bus_voltage_v * duty / resistance_ohm, rel=1e-6)
    stall_torque_nm = params.gear_ratio * params.torque_constant_nm_per_a * state.current_a
    assert state.spring_torque_nm == pytest.approx(stall_torque_nm, rel=1e-6)
    gearbox_output_rad = state.motor_angle_rad / params.gear_ratio
    deflection_rad = stall_torque_nm / params.spring_stiffness_nm_per_rad
    assert state.load_angle_rad == load_angle_rad
    assert gearbox_output_rad == pytest.approx(load_angle_rad + deflection_rad, rel=1e-6)


def test_set_load_motion_updates_the_spring_torque_and_keeps_the_rest() -> None:
    params = JointParams()
    plant = JointPlant(params, external_load=True, motor_angle_rad=5.0, current_a=1.0)
    before = plant.state
    after = plant.set_load_motion(0.05, 0.4)
    assert after is plant.state
    assert (after.motor_angle_rad, after.current_a, after.time_s) == (5.0, 1.0, before.time_s)
    expected_nm = params.spring_stiffness_nm_per_rad * (5.0 / params.gear_ratio - 0.05) + (
        params.spring_damping_nm_s_per_rad * (0.0 - 0.4)
    )
    assert after.spring_torque_nm == pytest.approx(expected_nm, rel=1e-12)


def test_external_load_rejects_misuse() -> None:
    with pytest.raises(ValueError, match="external_load=False"):
        JointPlant().set_load_motion(0.0, 0.0)
    coupled = JointPlant(external_load=True)
    with pytest.raises(ValueError, match="own simulator"):
        coupled.step(1e-3, 0.0, load_torque_nm=0.1)
    with pytest.raises(ValueError, match="finite"):
        coupled.set_load_motion(math.nan, 0.0)


# --- ChainPhysics ----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def mujoco() -> ModuleType:
    return pytest.importorskip("mujoco")


def _chain_module() -> ModuleType:
    """hilrig.plants.chain, imported inside the tests (it is importable without MuJoCo)."""
    from hilrig.plants import chain

    return chain


def _travelling_wave(module_count: int, time_s: float) -> list[float]:
    """The gait's duty pattern: A sin(omega t + i beta)."""
    return [0.3 * math.sin(2.0 * math.pi * time_s + 0.8 * index) for index in range(module_count)]


def _link_inertia_about_joint(mujoco: ModuleType, model: Any, body: int) -> float:
    """Inertia of `body` about the vertical axis through its frame, from the compiled model."""
    import numpy as np

    rotation = np.zeros(9)
    mujoco.mju_quat2Mat(rotation, model.body_iquat[body])
    rotation = rotation.reshape(3, 3)
    inertia = rotation @ np.diag(model.body_inertia[body]) @ rotation.T
    offset = model.body_ipos[body]
    return float(inertia[2, 2] + model.body_mass[body] * (offset[0] ** 2 + offset[1] ** 2))


def test_mjcf_compiles_to_the_chain_it_describes(mujoco: ModuleType) -> None:
    chain_module = _chain_module()
    params = [
        JointParams(
            load_viscous_friction_nm_s_per_rad=0.01 * (index + 1), load_coulomb_friction_nm=0.02 * index
        )
        for index in range(3)
    ]
    geometry = chain_module.ChainGeometry(timestep_s=5e-4)
    model = mujoco.MjModel.from_xml_string(chain_module.chain_mjcf(geometry, params))
    assert model.nbody == 1 + 4  # world, head, three links
    assert model.njnt == 4 and model.nq == 7 + 3 and model.nv == 6 + 3
    assert model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE
    assert model.opt.timestep == 5e-4
    for index, p in enumerate(params):
        joint = 1 + index
        assert model.jnt_type[joint] == mujoco.mjtJoint.mjJNT_HINGE
        assert tuple(model.jnt_axis[joint]) == (0.0, 0.0, 1.0)
        assert model.jnt_bodyid[joint] == 2 + index  # link index + 1, after world and head
        assert model.dof_damping[6 + index] == p.load_viscous_friction_nm_s_per_rad
        assert model.dof_frictionloss[6 + index] == p.load_coulomb_friction_nm
    # MuJoCo's own mass properties agree with the closed form the geometry documents.
    for body in range(1, 5):
        assert model.body_mass[body] == pytest.approx(geometry.link_mass_kg, rel=1e-12)
        assert _link_inertia_about_joint(mujoco, model, body) == pytest.approx(
            geometry.link_inertia_about_joint_kg_m2, rel=1e-9
        )


def test_default_link_has_the_single_joints_load_inertia_about_its_joint() -> None:
    chain_module = _chain_module()
    geometry = chain_module.ChainGeometry()
    assert geometry.link_inertia_about_joint_kg_m2 == pytest.approx(
        JointParams().load_inertia_kg_m2, rel=0.01
    )
    heavier = geometry.with_link_inertia(0.03)
    assert heavier.link_inertia_about_joint_kg_m2 == pytest.approx(0.03, rel=1e-12)
    assert heavier.link_mass_kg == pytest.approx(geometry.link_mass_kg * 0.03 / 0.0100325, rel=1e-3)


def test_zero_duty_keeps_the_snake_still(mujoco: ModuleType) -> None:
    chain = _chain_module().ChainPhysics(4)
    positions_before, _ = chain.poses()
    for _ in range(500):
        chain.step(1e-3, [0.0] * 4)
    positions_after, quaternions = chain.poses()
    assert chain.time_s == pytest.approx(0.5, abs=1e-12)
    for state in chain.states:
        assert abs(state.load_angle_rad) < 1e-12
        assert abs(state.spring_torque_nm) < 1e-9
        assert abs(state.current_a) < 1e-9
    moved = positions_after - positions_before
    assert abs(moved[:, :2]).max() < 1e-8  # nothing slides
    assert 0.0 < -moved[:, 2].min() < 1e-4  # only the settling into the soft ground contact
    assert abs(abs(quaternions[:, 0]) - 1.0).max() < 1e-9


def test_a_step_reads_no_clock_unless_the_caller_set_a_timer(mujoco: ModuleType) -> None:
    """MuJoCo's per-stage timers are off (each a clock read: a system call under user-mode
    Linux), so a step's timer stays at zero; a timer callback of the caller's own is kept."""
    chain = _chain_module().ChainPhysics(2)
    for _ in range(20):
        chain.step(1e-3, [0.2, -0.2])
    step_timer = chain.data.timer[mujoco.mjtTimer.mjTIMER_STEP]
    assert step_timer.number == 20 and step_timer.duration == 0.0
    ticks = itertools.count()
    mujoco.set_mjcb_time(lambda: float(next(ticks)))
    try:
        timed = _chain_module().ChainPhysics(2)
        timed.step(1e-3, [0.2, -0.2])
        assert timed.data.timer[mujoco.mjtTimer.mjTIMER_STEP].duration > 0.0
    finally:
        mujoco.set_mjcb_time(None)


def test_the_spring_torque_is_what_mujoco_applies_and_a_driven_joint_bends(mujoco: ModuleType) -> None:
    chain = _chain_module().ChainPhysics(3)
    duties = [0.0, 0.05, 0.0]
    for _ in range(200):
        before = chain.states
        chain.step(1e-3, duties)
        # One MuJoCo step per period: the torque over the period is the spring's at its start.
        expected = [state.spring_torque_nm for state in before]
        assert list(chain.applied_torques_nm) == expected
        assert chain.data.qfrc_applied[6:].tolist() == expected
        assert chain.data.qfrc_applied[:6].tolist() == [0.0] * 6
    angles = [state.load_angle_rad for state in chain.states]
    # The driven joint bends the way its duty pushes, further than its passive neighbours.
    assert angles[1] > 0.02
    assert abs(angles[1]) > 1.5 * max(abs(angles[0]), abs(angles[2]))
    # A joint's torque is internal: the neighbours turn the other way.
    assert angles[0] < 0.0 and angles[2] < 0.0


def test_several_mujoco_steps_per_period_blend_the_start_and_end_spring_torques(mujoco: ModuleType) -> None:
    chain_module = _chain_module()
    params = JointParams()
    chain = chain_module.ChainPhysics(2, params, chain_module.ChainGeometry(timestep_s=0.25e-3))
    assert chain.mujoco_steps_per_period(1e-3) == 4
    blend = 3.0 / 8.0  # (n - 1) / (2 n)
    for step in range(50):
        duties = [0.4, -0.2]
        before = chain.states
        chain.step(1e-3, duties)
        if step % 10 != 9:
            continue
        for index, start in enumerate(before):
            # The same motor side stepped alone against the same load motion.
            twin = JointPlant(
                params,
                external_load=True,
                motor_angle_rad=start.motor_angle_rad,
                motor_velocity_rad_s=start.motor_velocity_rad_s,
                load_angle_rad=start.load_angle_rad,
                load_velocity_rad_s=start.load_velocity_rad_s,
                current_a=start.current_a,
                winding_temperature_c=start.winding_temperature_c,
            )
            end_nm = twin.step(1e-3, duties[index]).spring_torque_nm
            expected_nm = start.spring_torque_nm + blend * (end_nm - start.spring_torque_nm)
            assert chain.applied_torques_nm[index] == pytest.approx(expected_nm, rel=1e-12, abs=1e-15)
            assert chain.data.qfrc_applied[6 + index] == chain.applied_torques_nm[index]


def test_stalled_joint_torque_balance(mujoco: ModuleType) -> None:
    """A small constant duty the ground's friction holds: the motor stalls (up to MuJoCo's soft
    friction's slow creep), the spring carries the motor torque through the gearbox and the
    joint angle is the gearbox output minus that deflection."""
    params = JointParams(copper_temperature_coefficient_per_k=0.0)  # R constant: a true steady state
    chain = _chain_module().ChainPhysics(3, params)
    duty = 0.002  # stall torque 50 * 0.05 * 24 * 0.002 / 1 = 0.12 N*m
    for _ in range(2500):  # 20 time constants of the rotor's slow pole (8 /s)
        chain.step(1e-3, [0.0, duty, 0.0])
    state = chain.states[1]
    p = params
    creep_rad_s = state.load_velocity_rad_s
    assert abs(creep_rad_s) < 0.01  # held, apart from the creep
    # Winding: no inductive drop at steady state; the creep's back-EMF is accounted for.
    current_a = (p.bus_voltage_v * duty - p.back_emf_constant_v_s_per_rad * state.motor_velocity_rad_s) / (
        p.winding_resistance_ohm
    )
    assert state.current_a == pytest.approx(current_a, rel=1e-4)
    # Rotor: motor torque = spring torque / N + friction.
    spring_nm = p.gear_ratio * (
        p.torque_constant_nm_per_a * state.current_a
        - p.motor_viscous_friction_nm_s_per_rad * state.motor_velocity_rad_s
    )
    assert state.spring_torque_nm == pytest.approx(spring_nm, rel=1e-3)
    assert state.spring_torque_nm == pytest.approx(0.12, rel=0.25)
    gearbox_output_rad = state.motor_angle_rad / p.gear_ratio
    assert state.load_angle_rad == pytest.approx(
        gearbox_output_rad - spring_nm / p.spring_stiffness_nm_per_rad, abs=1e-6
    )
    assert chain.applied_torques_nm[1] == pytest.approx(spring_nm, rel=1e-3)


@pytest.mark.parametrize("timestep_s", [1e-3, 0.5e-3])
def test_the_coupling_neither_makes_nor_loses_energy(mujoco: ModuleType, timestep_s: float) -> None:
    """Lossless springs and joints, frictionless ground, rotors held after a kick: the links'
    kinetic energy plus the springs' energy must stay put (holding the start torque over two
    MuJoCo steps multiplies it by ~2e4 in 2 s; the trapezoid with one step loses it all)."""
    chain_module = _chain_module()
    lossless = JointParams(
        spring_damping_nm_s_per_rad=0.0, load_viscous_friction_nm_s_per_rad=0.0, load_coulomb_friction_nm=0.0
    )
    geometry = chain_module.ChainGeometry(ground_friction=0.0, timestep_s=timestep_s)
    chain = chain_module.ChainPhysics(4, lossless, geometry)
    chain.model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    for _ in range(30):
        chain.step(1e-3, [0.2, -0.2, 0.2, -0.2])
    for plant in chain.plants:
        plant.set_motor_held(True)

    def energy_j() -> float:
        mujoco.mj_forward(chain.model, chain.data)  # energy at the present state (test only)
        springs = sum(
            0.5 * p.spring_stiffness_nm_per_rad * s.spring_deflection_rad**2
            for p, s in zip(chain.params, chain.states, strict=True)
        )
        return float(chain.data.energy[1]) + springs

    energies = []
    for _ in range(2000):
        chain.step(1e-3, [0.0] * 4)
        energies.append(energy_j())
    first, last = sum(energies[:200]) / 200, sum(energies[-200:]) / 200
    assert first > 1e-3  # there is something to conserve
    assert last == pytest.approx(first, rel=0.01)


def test_same_inputs_give_bit_identical_results(mujoco: ModuleType) -> None:
    chain_module = _chain_module()
    runs = []
    for _ in range(2):
        chain = chain_module.ChainPhysics(4)
        for step in range(400):
            chain.step(1e-3, _travelling_wave(4, step * 1e-3))
        positions, quaternions = chain.poses()
        arrays = (chain.data.qpos, chain.data.qvel, positions, quaternions)
        runs.append((chain.states, *(array.tobytes() for array in arrays)))
    assert runs[0] == runs[1]
    assert any(abs(state.load_angle_rad) > 0.01 for state in runs[0][0])  # it did move


@pytest.mark.parametrize("module_count", [1, 8])
def test_gait_poses_follow_the_joints(mujoco: ModuleType, module_count: int) -> None:
    """Under the travelling wave, each link frame sits one link length behind its parent's and
    is turned about their shared hinge by exactly its joint's angle: poses() and states agree."""
    import numpy as np

    chain = _chain_module().ChainPhysics(module_count)
    for step in range(600):
        chain.step(1e-3, _travelling_wave(module_count, step * 1e-3))
    positions, quaternions = chain.poses()
    assert positions.shape == (module_count + 1, 3) and quaternions.shape == (module_count + 1, 4)
    assert np.all(np.isfinite(positions)) and np.all(np.isfinite(quaternions))
    geometry = chain.geometry
    spacing = np.linalg.norm(np.diff(positions, axis=0), axis=1)
    assert spacing == pytest.approx([geometry.link_length_m] * module_count, rel=1e-6)
    # Relative rotation of link i+1 to link i: a turn about the hinge (z) by joint i's angle.
    relative = np.zeros(4)
    for index, state in enumerate(chain.states):
        parent_inverse = np.zeros(4)
        mujoco.mju_negQuat(parent_inverse, quaternions[index])
        mujoco.mju_mulQuat(relative, parent_inverse, quaternions[index + 1])
        angle = 2.0 * math.atan2(relative[3], relative[0])
        assert abs(relative[1]) < 1e-9 and abs(relative[2]) < 1e-9
        assert angle == pytest.approx(state.load_angle_rad, abs=1e-9)
    assert abs(positions[:, 2] - geometry.link_radius_m).max() < 0.01  # on the ground
    assert max(abs(state.load_angle_rad) for state in chain.states) > 0.05  # the gait moved them


def test_initial_joint_angles_bend_the_chain_with_relaxed_springs(mujoco: ModuleType) -> None:
    angles = [0.4, -0.3, 0.2]
    chain = _chain_module().ChainPhysics(3, initial_joint_angles_rad=angles)
    for state, angle, params in zip(chain.states, angles, chain.params, strict=True):
        assert state.load_angle_rad == angle
        assert state.motor_angle_rad == angle * params.gear_ratio
        assert state.spring_torque_nm == 0.0
    _, quaternions = chain.poses()
    headings = [2.0 * math.atan2(q[3], q[0]) for q in quaternions]
    assert [b - a for a, b in itertools.pairwise(headings)] == pytest.approx(angles, abs=1e-12)
    for _ in range(300):  # nothing pushes: the bent snake stays as it is
        chain.step(1e-3, [0.0] * 3)
    # Settling into the soft ground contact nudges a bent chain by < 1e-6 rad.
    assert [state.load_angle_rad for state in chain.states] == pytest.approx(angles, abs=1e-5)


def test_argument_errors(mujoco: ModuleType) -> None:
    chain_module = _chain_module()
    for bad in (0, -1, True, 1.5):
        with pytest.raises(ValueError, match="module_count"):
            chain_module.ChainPhysics(bad)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="module count"):
        chain_module.chain_mjcf(chain_module.ChainGeometry(), [])
    with pytest.raises(ValueError, match="params"):
        chain_module.ChainPhysics(3, [JointParams()] * 2)
    with pytest.raises(ValueError, match="timestep_s"):
        chain_module.ChainGeometry(timestep_s=0.0)
    chain = chain_module.ChainPhysics(2)
    for period_s in (1.5e-3, 0.5e-3, 0.0, -1e-3, math.nan):
        with pytest.raises(ValueError, match="whole number of MuJoCo steps"):
            chain.step(period_s, [0.1, 0.1])
    with pytest.raises(ValueError, match="duties"):
        chain.step(1e-3, [0.1])
    with pytest.raises(ValueError, match="finite"):
        chain.step(1e-3, [0.1, math.inf])
    assert chain.time_s == 0.0 and chain.data.time == 0.0  # nothing moved
    chain.step(3e-3, [0.1, 0.1])  # three MuJoCo steps: fine
    assert chain.data.time == pytest.approx(3e-3, abs=1e-15)


def test_a_diverging_chain_raises(
    mujoco: ModuleType, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Links far too light for a 1 ms coupling (omega * dt ~ 20): an error, not a silent reset."""
    monkeypatch.chdir(tmp_path)  # MuJoCo's warning goes to ./MUJOCO_LOG.TXT too
    chain_module = _chain_module()
    chain = chain_module.ChainPhysics(2, geometry=chain_module.ChainGeometry(link_mass_kg=1e-5))
    with pytest.raises(FloatingPointError, match="diverged"):
        for _ in range(1000):
            chain.step(1e-3, [0.5, 0.0])
    assert chain.time_s < 0.1  # caught at once, not after a reset


def test_missing_mujoco_says_how_to_install_it(monkeypatch: pytest.MonkeyPatch) -> None:
    import sys

    chain_module = _chain_module()
    monkeypatch.setitem(sys.modules, "mujoco", None)  # import mujoco -> ImportError
    with pytest.raises(ImportError, match=r"pip install 'hilrig\[robot\]'"):
        chain_module.ChainPhysics(1)


def test_the_single_joint_rig_does_not_import_mujoco() -> None:
    import subprocess
    import sys

    code = "import sys, hilrig.plants, hilrig.plants.chain; assert 'mujoco' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True)
