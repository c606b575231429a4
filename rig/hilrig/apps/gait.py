"""The snake's gait: a travelling wave the robot's position loops follow (an app's scenario
over the engine's `Robot`, on the demo joint's fields: position mode, its loop gain and setpoint).

    from hilrig.apps.gait import TravellingWave
    wave = TravellingWave(phase_per_joint_rad=2 * math.pi / 3).drive(robot)
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

from hilrig.engine.robot import Robot
from hilrig.table import ControlMode

GAIT_POSITION_KP = 100.0
"""Position loop gain for the gait [1/s] (board default 5: a setpoint step's gentle approach).
The firmware's position loop is proportional with no velocity feed-forward, so a sine of angular
frequency w lags by about w / kp of its amplitude plus the velocity loop's own lag. Measured on
8 modules, 0.5 rad at 0.5 Hz, largest |commanded - measured| after the ramp: kp 40 0.121 rad,
kp 100 0.094 rad (the middle joints, which move the most mass; velocity_kp 0.3 instead of 0.1
changed nothing)."""


@dataclass(frozen=True)
class TravellingWave:
    """The snake's lateral undulation: joint i follows amplitude * sin(2 pi f t + i * phase) [rad],
    the amplitude eased in from 0 over `ramp_s` (a wave started at full amplitude would be a step
    of up to the amplitude on most joints at t = 0).

    The defaults make one whole wave along 8 modules (phase 2 pi / 8 each) at 0.5 Hz, 0.5 rad: a
    slow gait a 1 kHz position loop tracks closely, fast enough that 2 s of simulation show it."""

    amplitude_rad: float = 0.5
    frequency_hz: float = 0.5
    phase_per_joint_rad: float = 2 * math.pi / 8
    ramp_s: float = 0.5
    start_s: float = 0.0
    """When the wave starts (`drive` sets it to the robot's time)."""

    def angles(self, t: float, joints: int) -> list[float]:
        """Every joint's commanded angle at `t` [s]."""
        since = t - self.start_s
        if since <= 0.0:
            return [0.0] * joints
        ease = 1.0 if since >= self.ramp_s else 0.5 - 0.5 * math.cos(math.pi * since / self.ramp_s)
        amplitude = self.amplitude_rad * ease
        base = 2 * math.pi * self.frequency_hz * since
        return [amplitude * math.sin(base + i * self.phase_per_joint_rad) for i in range(joints)]

    def drive(self, robot: Robot, *, position_kp: float = GAIT_POSITION_KP) -> TravellingWave:
        """Make `robot` follow the wave from now on: position mode with a loop gain fit for it,
        and before every cycle each module's position_setpoint for that cycle's time. Returns
        the wave as driven (its `start_s` is the robot's time now)."""
        wave = dataclasses.replace(self, start_s=robot.t)
        joints = len(robot.joints)
        robot.set_all("position_kp", position_kp)
        robot.set_each("position_setpoint", wave.angles(robot.t, joints))
        robot.set_all("control_mode", ControlMode.POSITION)
        robot.before_each_cycle(lambda r: r.set_each("position_setpoint", wave.angles(r.t, joints)))
        return wave


__all__ = ["GAIT_POSITION_KP", "TravellingWave"]
