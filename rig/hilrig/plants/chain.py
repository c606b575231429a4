"""A chain of N joint modules, a snake on the ground: MuJoCo for the links, JointPlant per joint.

Mechanics only (no bus). N identical modules in series: N + 1 capsule links lying on a plane
with friction, joined by N hinges whose axes are vertical (lateral undulation). The head link
(link 0) has a free joint; link i + 1 hangs on link i through joint i. Each joint's motor,
gearbox, series spring, winding heat (and, through SensorModel, its sensors) stay the rig's
own JointPlant, built with `external_load=True`: MuJoCo owns the load side (the links, their
inertia, the joint's bearing friction and the ground contacts) and the plant owns the rest.

Coupling, once per control period dt (explicit co-simulation, `ChainPhysics.step`):
1. Each plant starts from MuJoCo's joint angle and speed (set_load_motion at the end of the
   previous period), so its state's spring torque tau_start is the spring's torque now.
2. The plant steps dt with its duty while its load moves on at that speed (infinite load
   inertia); the new state's spring torque tau_end is the torque at the end of the period
   for that predicted load motion.
3. MuJoCo gets tau = tau_start + alpha * (tau_end - tau_start) as a generalized force
   (qfrc_applied) on the joint, held for the n = dt / timestep MuJoCo steps of the period,
   alpha = (n - 1) / (2 n); the reaction goes to the parent link (the motor's housing).
4. MuJoCo's new joint angles and speeds go back into the plants (step 1 of the next period).

Why alpha and why it is stable: MuJoCo's integrator is semi-implicit Euler; n of its steps
under a constant torque move the load by dt*v + beta*dt^2*a with beta = (n + 1) / (2 n). For
a spring k on a load J (omega^2 = k / J, x = omega * dt) the period map then has determinant
1 + (1 - alpha - beta) * x^2, which is exactly 1 (no energy made or lost by the coupling)
when alpha + beta = 1. With n = 1 (the default: MuJoCo's step is the 1 ms control period)
alpha = 0: the torque at the start of the period, and spring plus load are integrated by
symplectic Euler, stable for x < 2. The default joint in this chain: link inertia about its
joint 0.010 kg*m^2, but the free chain yields, so the smallest effective joint inertia is
0.0018 kg*m^2 (N = 1); with the reflected rotor 0.025 kg*m^2 the stiffest spring mode is
sqrt(50 * (1/0.0018 + 1/0.025)) = 174 rad/s, x = 0.17 at 1 ms: far inside. A linearised
analysis of the full period map (rotor integrated exactly against the predicted load) gives
decay rates within 0.5 % of the exact ones (1.00 /s held rotor, 1.41 /s free rotor for the
spring damping of the default joint), where holding tau_start with n > 1 would add
omega^2 dt / 4 of growth and tau_end alone the same amount of false damping.

Known limits of the model (MuJoCo's defaults, kept for cost): its soft friction lets a
stalled chain creep (about 4 mrad/s at a joint holding 0.12 N*m; noslip_iterations = 2
cuts that ~200-fold for ~+10 % step time), and round links roll: a near-straight snake is a
cylinder, so under the gait its links tilt by up to ~15 degrees about their long axis.
The rotor's own inertia is simulated in its housing's frame (the parent link's rotation
does not reach it: J_rotor = 1e-5 against links of 1e-2 kg*m^2).

MuJoCo is imported only here, and lazily: the single-joint rig does not need it.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from hilrig.plants.joint import JointModel
from hilrig.plants.params import JointParams
from hilrig.plants.plant import JointPlant, JointState
from hilrig.plants.sensors import SensorModel

if TYPE_CHECKING:
    import numpy as np

INSTALL_HINT = "pip install 'hilrig[robot]'"

_FREE_JOINT_QPOS = 7
"""qpos entries of the head's free joint (position xyz, quaternion wxyz); the hinges follow."""
_FREE_JOINT_DOFS = 6
"""Degrees of freedom of the free joint (linear, angular); the hinges' dofs follow."""
_PERIOD_TOLERANCE = 1e-9
"""Relative slack when checking that a period is a whole number of MuJoCo steps."""


def _import_mujoco() -> Any:
    try:
        import mujoco
    except ImportError as error:
        raise ImportError(f"the chain of joint modules needs MuJoCo: {INSTALL_HINT}") from error
    return mujoco


def capsule_inertia_about_end_kg_m2(mass_kg: float, length_m: float, radius_m: float) -> float:
    """Inertia of a uniform capsule about an axis through one end of its segment, across it.

    The capsule: a cylinder of `length_m` (the segment, joint to joint) with hemispherical
    caps of `radius_m`, mass shared by volume (as MuJoCo does for a geom given its mass).
    """
    cylinder_volume = math.pi * radius_m**2 * length_m
    sphere_volume = 4.0 / 3.0 * math.pi * radius_m**3
    cylinder_mass = mass_kg * cylinder_volume / (cylinder_volume + sphere_volume)
    caps_mass = mass_kg - cylinder_mass
    about_centre = cylinder_mass * (3.0 * radius_m**2 + length_m**2) / 12.0 + caps_mass * (
        2.0 * radius_m**2 / 5.0 + length_m**2 / 4.0 + 3.0 * length_m * radius_m / 8.0
    )
    return about_centre + mass_kg * (length_m / 2.0) ** 2


@dataclass(frozen=True, slots=True)
class ChainGeometry:
    """The links, the ground and MuJoCo's step: everything of the chain that is not a JointParams.

    Defaults: a module 0.2 m joint to joint, 7 cm across, 0.65 kg, i.e. 690 kg/m^3 (a motor
    and gearbox in a light shell). Its inertia about its joint is then 0.0100 kg*m^2, the
    single-joint rig's default load inertia (JointParams.load_inertia_kg_m2): the tail joint
    moves about one link, like the single joint moves its load; inner joints move more.
    """

    link_length_m: float = 0.2
    """Joint to joint distance, the length of each capsule's segment [m]."""
    link_radius_m: float = 0.035
    """Capsule radius [m]."""
    link_mass_kg: float = 0.65
    """Mass of one link (module) [kg]."""
    ground_friction: float = 0.5
    """Sliding friction coefficient between links and ground (isotropic) [1]."""
    timestep_s: float = 1e-3
    """MuJoCo's step [s]; a control period must be a whole number of them. 1 ms: half
    MuJoCo's default 2 ms (its contacts' 20 ms time constant wants <= 10 ms), and one
    MuJoCo step per 1 ms control period, the cheapest that keeps the coupling exact."""

    def __post_init__(self) -> None:
        for name in ("link_length_m", "link_radius_m", "link_mass_kg", "timestep_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"ChainGeometry.{name}: expected finite > 0, got {value}")
        if not (math.isfinite(self.ground_friction) and self.ground_friction >= 0.0):
            raise ValueError(
                f"ChainGeometry.ground_friction: expected finite >= 0, got {self.ground_friction}"
            )

    @property
    def link_inertia_about_joint_kg_m2(self) -> float:
        """One link's inertia about its joint axis (vertical, through the segment's end)."""
        return capsule_inertia_about_end_kg_m2(self.link_mass_kg, self.link_length_m, self.link_radius_m)

    def with_link_inertia(self, inertia_kg_m2: float) -> ChainGeometry:
        """A copy whose link mass gives `inertia_kg_m2` about the joint, same shape."""
        if not (math.isfinite(inertia_kg_m2) and inertia_kg_m2 > 0.0):
            raise ValueError(f"inertia_kg_m2: expected finite > 0, got {inertia_kg_m2}")
        per_kg = capsule_inertia_about_end_kg_m2(1.0, self.link_length_m, self.link_radius_m)
        return dataclasses.replace(self, link_mass_kg=inertia_kg_m2 / per_kg)


def chain_mjcf(geometry: ChainGeometry, joint_params: Sequence[JointParams]) -> str:
    """The MJCF of a chain with one module per entry of `joint_params`.

    Bodies link_0 (head, free joint) .. link_N; hinge joint_i (axis z) between link_i and
    link_i+1, its damping and frictionloss the module's load viscous and Coulomb friction
    (MuJoCo's frictionloss is a hard Coulomb limit, not the plant's tanh ramp). Each body's
    frame sits on its joint (the head's on its front end); its capsule runs back along the
    body's -x axis. The snake starts straight along -x from the origin, resting on the
    ground (z = radius), head pointing +x. Adjacent links do not collide (MuJoCo filters
    parent and child); others do.
    """
    if len(joint_params) < 1:
        raise ValueError(f"module count: expected >= 1, got {len(joint_params)}")
    g = geometry
    length, radius = repr(g.link_length_m), repr(g.link_radius_m)
    # Frictionless ground: normal-only contacts (condim 1); MuJoCo's friction pyramid with a
    # zero coefficient is degenerate and blows up.
    contact = (
        f'condim="3" friction="{g.ground_friction!r} 0.005 0.0001"'
        if g.ground_friction > 0.0
        else 'condim="1"'
    )
    capsule = (
        f'<geom name="{{name}}" type="capsule" fromto="0 0 0 -{length} 0 0" size="{radius}" '
        f'mass="{g.link_mass_kg!r}" {contact}/>'
    )
    opened = [
        f'<body name="link_0" pos="0 0 {radius}">',
        '<freejoint name="head"/>',
        capsule.format(name="link_0"),
    ]
    for index, params in enumerate(joint_params):
        opened += [
            f'<body name="link_{index + 1}" pos="-{length} 0 0">',
            f'<joint name="joint_{index}" type="hinge" axis="0 0 1" '
            f'damping="{params.load_viscous_friction_nm_s_per_rad!r}" '
            f'frictionloss="{params.load_coulomb_friction_nm!r}"/>',
            capsule.format(name=f"link_{index + 1}"),
        ]
    bodies = "\n      ".join(opened) + "\n      " + "</body>" * (len(joint_params) + 1)
    return f"""<mujoco model="chain_of_{len(joint_params)}_modules">
  <compiler angle="radian"/>
  <option timestep="{g.timestep_s!r}" integrator="implicitfast">
    <!-- A diverging state must fail loudly (step() raises), not restart from qpos0. -->
    <!-- One kinematic tree is one constraint island: finding islands is pure overhead. -->
    <flag autoreset="disable" island="disable"/>
  </option>
  <worldbody>
    <geom name="ground" type="plane" size="0 0 1" {contact}/>
      {bodies}
  </worldbody>
</mujoco>
"""


class ChainPhysics:
    """N joint modules in series on the ground, advanced one control period at a time.

    `step(dt_s, duties)` advances the plants and MuJoCo together (see the module docstring);
    `models` are the modules as `hilrig.plants.interface.Plant`s (module k's sensor noise of
    seed `seed * 1000 + k`), whose applied duties `step(dt_s)` takes when given none;
    `states` are the modules' JointStates (load angle and speed = MuJoCo's joints, spring
    torque = the spring's torque now); `poses()` the links' frames for a 3D view. Same
    inputs give bit-identical results (MuJoCo runs single-threaded, no randomness).
    """

    def __init__(
        self,
        module_count: int,
        params: JointParams | Sequence[JointParams] | None = None,
        geometry: ChainGeometry | None = None,
        *,
        initial_joint_angles_rad: Sequence[float] | None = None,
        seed: int = 0,
    ) -> None:
        """A straight chain at rest (or bent to `initial_joint_angles_rad`, springs relaxed).

        params: one JointParams for every module, or one per module; its load inertia is
        not used (the links are the load), its load friction becomes the MuJoCo joint's.
        Raises ValueError for module_count < 1 or a params/angles count that does not match,
        ImportError when MuJoCo is missing.
        """
        if isinstance(module_count, bool) or not isinstance(module_count, int) or module_count < 1:
            raise ValueError(f"module_count: expected an int >= 1, got {module_count!r}")
        if params is None or isinstance(params, JointParams):
            per_module = (params if params is not None else JointParams(),) * module_count
        else:
            per_module = tuple(params)
            if len(per_module) != module_count:
                raise ValueError(f"params: expected {module_count} JointParams, got {len(per_module)}")
        angles = (
            tuple(initial_joint_angles_rad) if initial_joint_angles_rad is not None else (0.0,) * module_count
        )
        if len(angles) != module_count or not all(math.isfinite(angle) for angle in angles):
            raise ValueError(f"initial_joint_angles_rad: expected {module_count} finite angles, got {angles}")
        mujoco = _import_mujoco()
        self._geometry = geometry if geometry is not None else ChainGeometry()
        self._params = per_module
        self._mjcf = chain_mjcf(self._geometry, per_module)
        self._model = mujoco.MjModel.from_xml_string(self._mjcf)
        self._data = mujoco.MjData(self._model)
        if mujoco.get_mjcb_time() is None:
            # MuJoCo's Python bindings time each stage of a step (MjData.timer, which nothing
            # here reads): 31 clock reads a step. Under user-mode Linux, which has no vDSO, each
            # is a system call of some 30 us: a millisecond of every robot cycle. Off after the
            # MjData (a new one turns them on again); a timer callback set by the caller is kept.
            mujoco.set_mjcb_time(None)
        self._mj_step = mujoco.mj_step
        self._mj_kinematics = mujoco.mj_kinematics
        # Views into MjData's fixed buffers: the hinges follow the head's free joint.
        self._joint_angles_view = self._data.qpos[_FREE_JOINT_QPOS:]
        self._joint_velocities_view = self._data.qvel[_FREE_JOINT_DOFS:]
        self._joint_torques_view = self._data.qfrc_applied[_FREE_JOINT_DOFS:]
        self._joint_angles_view[:] = angles
        mujoco.mj_kinematics(self._model, self._data)
        # Springs relaxed: each gearbox output sits where its joint is.
        self._plants = tuple(
            JointPlant(p, motor_angle_rad=angle * p.gear_ratio, load_angle_rad=angle, external_load=True)
            for p, angle in zip(per_module, angles, strict=True)
        )
        self._states = [plant.state for plant in self._plants]
        self._models = tuple(
            JointModel(plant, SensorModel(p, seed * 1000 + k), stepped_by="its chain (ChainPhysics.step)")
            for k, (plant, p) in enumerate(zip(self._plants, per_module, strict=True))
        )
        self._applied_torques_nm = [0.0] * module_count
        self._steps_per_period: dict[float, int] = {}

    # --- Description ----------------------------------------------------------------------
    @property
    def module_count(self) -> int:
        return len(self._plants)

    @property
    def link_count(self) -> int:
        """Links (capsules, bodies): one more than the modules (the head)."""
        return len(self._plants) + 1

    @property
    def geometry(self) -> ChainGeometry:
        return self._geometry

    @property
    def params(self) -> tuple[JointParams, ...]:
        return self._params

    @property
    def mjcf(self) -> str:
        """The MJCF the model was compiled from."""
        return self._mjcf

    @property
    def model(self) -> Any:
        """MuJoCo's MjModel (read it; changing it behind the plants' back breaks the coupling)."""
        return self._model

    @property
    def data(self) -> Any:
        """MuJoCo's MjData (read it; qfrc_applied of the hinges is overwritten every step)."""
        return self._data

    @property
    def plants(self) -> tuple[JointPlant, ...]:
        """The modules' plants: hold a rotor or change the ambient temperature through them."""
        return self._plants

    @property
    def models(self) -> tuple[JointModel, ...]:
        """The modules as plants of the interface (`hilrig.plants.interface.Plant`): a robot's
        module rig drives one each; the chain steps them all (`step`)."""
        return self._models

    # --- State ------------------------------------------------------------------------------
    @property
    def time_s(self) -> float:
        return self._states[0].time_s

    @property
    def states(self) -> tuple[JointState, ...]:
        """One JointState per module; load angle and speed are MuJoCo's joint."""
        return tuple(self._states)

    @property
    def applied_torques_nm(self) -> tuple[float, ...]:
        """The joint torques MuJoCo was given over the last period, one per module [N*m]."""
        return tuple(self._applied_torques_nm)

    def poses(self) -> tuple[np.ndarray, np.ndarray]:
        """Link frames now: positions (links x 3) [m] and quaternions wxyz (links x 4), copies.

        Each frame sits on the link's joint (the head's: its front end); the capsule
        (geometry.link_length_m, geometry.link_radius_m) runs back along the frame's -x axis.
        """
        # mj_step leaves xpos/xquat at the start of its last step: bring them to qpos now. The
        # next mj_step recomputes them anyway, so this changes nothing in the simulation.
        self._mj_kinematics(self._model, self._data)
        return self._data.xpos[1:].copy(), self._data.xquat[1:].copy()

    # --- Advancing -------------------------------------------------------------------------
    def mujoco_steps_per_period(self, dt_s: float) -> int:
        """MuJoCo steps in a control period of `dt_s`; ValueError unless a whole number >= 1."""
        steps = self._steps_per_period.get(dt_s)
        if steps is not None:
            return steps
        timestep_s = self._geometry.timestep_s
        ratio = dt_s / timestep_s if math.isfinite(dt_s) and dt_s > 0.0 else math.nan
        steps = round(ratio) if math.isfinite(ratio) else 0
        if steps < 1 or abs(ratio - steps) > _PERIOD_TOLERANCE * steps:
            raise ValueError(
                f"dt_s: {dt_s} s is not a whole number of MuJoCo steps of {timestep_s} s "
                "(choose ChainGeometry.timestep_s to divide the control period)"
            )
        self._steps_per_period[dt_s] = steps
        return steps

    def step(self, dt_s: float, duties: Sequence[float] | None = None) -> None:
        """Advance every module and the links by one control period `dt_s` [s].

        duties: one per module, fractions of the bus voltage (clamped to [-1, 1] by each
        plant); None: each module's as last applied to its model (`models`). Raises ValueError
        for a wrong count, a non-finite duty or a period that is not a whole number of MuJoCo
        steps (nothing has moved then), FloatingPointError if the simulation diverges.
        """
        steps = self.mujoco_steps_per_period(dt_s)
        plants = self._plants
        if duties is None:
            duties = [model.duty for model in self._models]
        if len(duties) != len(plants):
            raise ValueError(f"duties: expected {len(plants)}, got {len(duties)}")
        if not all(map(math.isfinite, duties)):
            raise ValueError(f"duties: expected finite numbers, got {list(duties)}")
        blend = (steps - 1) / (2 * steps)
        torques = self._applied_torques_nm
        for index, plant in enumerate(plants):
            start_nm = plant.state.spring_torque_nm
            end_nm = plant.step(dt_s, duties[index]).spring_torque_nm
            torques[index] = start_nm + blend * (end_nm - start_nm)
        self._joint_torques_view[:] = torques
        self._mj_step(self._model, self._data, steps)
        angles = self._joint_angles_view.tolist()
        velocities = self._joint_velocities_view.tolist()
        if not math.isfinite(sum(angles) + sum(velocities)):
            raise FloatingPointError(f"chain diverged at t = {self.time_s:.6f} s: joint angles {angles}")
        states = self._states
        for index, plant in enumerate(plants):
            states[index] = plant.set_load_motion(angles[index], velocities[index])
