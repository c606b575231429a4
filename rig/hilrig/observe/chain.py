"""A robot's chain in a trace: each link a capsule moved by the chain's pose, the robot's events."""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

import numpy as np

from hilrig.engine.robot import ROBOT_EVENTS_PATH, RobotObserver
from hilrig.observe.paths import CYCLE_TIMELINE, ROBOT_ROOT, link_path
from hilrig.observe.sinks import Severity

if TYPE_CHECKING:
    from hilrig.engine.robot import ChainModel, Robot

class ChainTrace(RobotObserver):
    """A robot's 3D view and events on its tracer's recording: each link a capsule at
    /robot/links/<k>, moved by the chain's pose every cycle (batched like the fields: one
    `send_columns` per link and batch, on the tracer's sender thread)."""

    def __init__(self, tracer: Any, chain: ChainModel) -> None:
        self._tracer = tracer
        self._chain = chain
        self._cycles: list[int] = []
        self._times: list[float] = []
        self._positions: list[np.ndarray] = []
        self._quaternions: list[np.ndarray] = []
        self._next_hand_over = time.monotonic() + (tracer.max_latency_s or 0.0)
        self._log_geometry()

    def _log_geometry(self) -> None:
        rr = self._tracer._rr
        recording = self._tracer.recording
        geometry = self._chain.geometry
        length, radius = geometry.link_length_m, geometry.link_radius_m
        # A capsule lies along +z from its origin; each link runs back along its frame's -x.
        along_minus_x = rr.RotationAxisAngle(axis=[0.0, 1.0, 0.0], degrees=-90.0)
        for k in range(self._chain.link_count):
            recording.log(
                link_path(k),
                rr.Capsules3D(
                    lengths=[length],
                    radii=[radius],
                    rotation_axis_angles=[along_minus_x],
                    colors=[(70, 130, 180) if k else (220, 120, 40)],  # the head stands out
                    labels=["head" if k == 0 else f"link {k}"],
                ),
                static=True,
            )
        # A patch of ground about the chain's length across, under the chain as it starts (from
        # the head at the origin back along -x): the 3D view frames it and the chain.
        chain_length = length * self._chain.link_count
        extent = 0.6 * chain_length
        recording.log(
            f"{ROBOT_ROOT}/ground",
            rr.Boxes3D(
                half_sizes=[[extent, extent, 0.001]],
                centers=[[-0.5 * chain_length, 0.0, -0.001]],
                colors=[(200, 200, 190)],
            ),
            static=True,
        )

    def on_robot_cycle(self, robot: Robot, cycle: int, t: float) -> None:
        positions, quaternions = self._chain.poses()
        self._cycles.append(cycle)
        self._times.append(t)
        self._positions.append(positions)
        self._quaternions.append(quaternions)
        tracer = self._tracer
        if len(self._cycles) >= tracer.batch_cycles or (
            tracer.max_latency_s is not None and time.monotonic() >= self._next_hand_over
        ):
            self.flush()

    def on_robot_event(self, text: str, *, warning: bool, cycle: int, t: float) -> None:
        level = Severity.WARN if warning else Severity.INFO
        self._tracer.log_text(ROBOT_EVENTS_PATH, text, level, t=t, cycle=cycle)

    def flush(self) -> None:
        """Hand the poses collected so far to the sender (close() of the robot's session)."""
        if self._tracer.max_latency_s is not None:
            self._next_hand_over = time.monotonic() + self._tracer.max_latency_s
        if not self._cycles:
            return
        cycles = np.asarray(self._cycles, dtype=np.int64)
        times = np.asarray(self._times, dtype=np.float64)
        positions = np.stack(self._positions)  # cycles x links x 3
        quaternions = np.stack(self._quaternions)[:, :, [1, 2, 3, 0]]  # MuJoCo wxyz -> Rerun xyzw
        self._cycles, self._times, self._positions, self._quaternions = [], [], [], []
        tracer = self._tracer

        def send() -> None:
            rr = tracer._rr
            indexes = [rr.TimeColumn(CYCLE_TIMELINE, sequence=cycles), tracer._time_column(times)]
            for k in range(positions.shape[1]):
                tracer.recording.send_columns(
                    link_path(k),
                    indexes=indexes,
                    columns=rr.Transform3D.columns(translation=positions[:, k], quaternion=quaternions[:, k]),
                )

        tracer.submit(send)

