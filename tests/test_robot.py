"""A modular robot on one bus: N joint modules (the same firmware started N times), one SYNC per
cycle for all, the chain's mechanics from MuJoCo, the rig as the master with its heartbeat.
Lockstep and seeded: every number here is reproducible."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import run_hilrig

from hilrig import resources
from hilrig.apps.gait import TravellingWave
from hilrig.engine.robot import MasterHeartbeat, Robot, RobotObserver
from hilrig.observe.dashboard_check import fitting_dashboards, trace_gaps
from hilrig.observe.reader import Trace
from hilrig.plants.head import HeadParams, HeadPlant
from hilrig.session.builder import Rider
from hilrig.table import EmcyCode, FaultFlags, RigTable

pytestmark = [pytest.mark.bus, pytest.mark.xdist_group("robot")]
"""One worker runs the robots one after another (`--dist loadgroup`, tools/run-tests): two at
once put 20 firmware processes and two chains on the VM's two vCPUs, and a 4-module robot beside
the 16-module one took 30 times its quiet time (load 15 to 30 from other work on the host)."""

TABLE = RigTable.load()
GAIT = TravellingWave()
SETTLE_S = GAIT.ramp_s + 0.5
"""The wave eases in over its ramp, and the chain takes a moment to follow: tracking is judged
from here on."""
TRACKING_TOLERANCE_RAD = 0.12
"""Largest |commanded - measured| joint angle once settled, about a quarter of the wave's
amplitude: the firmware's position loop is proportional only, so a sine lags (GAIT_POSITION_KP);
the middle joints of 8, which move the most mass, come closest (0.094 rad measured)."""


class EventLog(RobotObserver):
    """The robot's events as a test sees them (the trace gets the same through the same hook)."""

    def __init__(self) -> None:
        self.events: list[tuple[int, str]] = []

    def on_robot_event(self, text: str, *, warning: bool, cycle: int, t: float) -> None:
        self.events.append((cycle, text))


def tracking_error(robot: Robot, node_id: int, since_s: float, until_s: float | None = None) -> float:
    """Largest |position_setpoint - output_position| of a module over [since_s, until_s], cycle
    by cycle (the angle the node measured at the start of the cycle the setpoint went out in)."""
    module = robot.module(node_id)
    t_cmd, commanded = module.sent("position_setpoint")
    t_meas, measured = module.history("output_position")
    times, in_cmd, in_meas = np.intersect1d(t_cmd, t_meas, return_indices=True)
    window = (times >= since_s) & (times <= (until_s if until_s is not None else np.inf))
    assert window.any(), f"node {node_id}: no cycle with both values in [{since_s}, {until_s}] s"
    return float(np.max(np.abs(commanded[in_cmd][window] - measured[in_meas][window])))


@pytest.mark.requirement("CHAIN_01")
def test_travelling_wave_tracked_by_all_eight_modules(make_robot) -> None:
    session = make_robot(8)
    robot = session.robot
    positions_at_rest, _ = robot.chain.poses()
    GAIT.drive(robot)
    robot.run(seconds=2.0)
    errors = {node_id: tracking_error(robot, node_id, SETTLE_S) for node_id in robot.node_ids}
    print(
        f"\ntravelling wave, max |commanded - measured| after {SETTLE_S:g} s: "
        + ", ".join(f"node {n}: {e:.4f} rad" for n, e in errors.items())
    )
    for node_id, error in errors.items():
        assert error <= TRACKING_TOLERANCE_RAD, f"node {node_id} tracks within {error:.3f} rad"
    # The encoders report what the mechanics did: each module's measured angle is its link's
    # joint angle in MuJoCo (within the output encoder's resolution and a cycle's motion).
    for node_id in robot.node_ids:
        module = robot.module(node_id)
        _, measured = module.history("output_position")
        _, truth = module.truth("load_angle")
        assert abs(measured[-1] - truth[-2]) < 0.01, f"node {node_id}: {measured[-1]} vs {truth[-2]}"
    # The body moved: the wave bent the chain (the 3D view shows the same poses).
    positions, _ = robot.chain.poses()
    assert np.max(np.linalg.norm(positions - positions_at_rest, axis=1)) > 0.01
    session.close()
    trace = Trace.read(session.trace_path)
    for node_id in robot.node_ids:
        assert trace.scalars[f"/modules/{node_id}/fields/sensors/output_position"], node_id
    assert len(trace.cycles["/robot/links/0"]) == robot.cycle, "one pose of the head per cycle"
    # Every series the robot dashboard names for these modules has data (the browser stage shows
    # this trace in it).
    assert list(fitting_dashboards(trace)) == ["robot"]
    assert trace_gaps(trace) == []


def test_mixed_robot_the_snakes_joints_and_the_head_module_on_one_bus(make_robot) -> None:
    """Two boards in one robot: three joints and the head module (its own firmware, table and
    plant, protocol/boards/head.toml) on one bus, one SYNC and one exchange a cycle for all. The
    joints follow the gait, the head its LED command, every module answers every cycle, and
    nothing faults (the head watches the same master heartbeat). The head rides the snake's head
    link: its gyro reads the yaw the gait gives that link in MuJoCo."""
    head_table = RigTable.load(resources.HEAD_TABLE)
    head_params = HeadParams.from_table(head_table.board)
    rider = Rider(
        node_id=head_table.board.node.default_node_id,
        table=head_table,
        eds=resources.board_files(resources.HEAD_TABLE).eds,
        executable=resources.HEAD_FIRMWARE,
        plant=lambda _params, seed: HeadPlant(head_params, seed),
    )
    session = make_robot(3, riders=[rider])
    robot = session.robot
    head = robot.module(rider.node_id)
    assert robot.riders == (head,) and len(robot.joints) == 3
    head.plant.mount_on(lambda: robot.chain.poses()[1][0])  # link 0: the snake's head
    wave = TravellingWave(phase_per_joint_rad=2 * np.pi / 3, ramp_s=0.2).drive(robot)
    robot.set_all("led_green", 1.0)  # the head's field: set on the head only
    robot.run(seconds=0.6)
    settled_s = wave.ramp_s + 0.2
    for joint in robot.joints:
        error = tracking_error(robot, joint.node.node_id, settled_s)
        assert error <= TRACKING_TOLERANCE_RAD, f"node {joint.node.node_id} tracks within {error:.3f} rad"
    _, green = head.history("led_green_pwm")
    assert green[-1] == 255, f"expected the head's green LED at 255, got {green[-1]}"
    _, closed = head.truth("rail_closed")
    assert closed[-1] == 1.0
    for module in robot.modules:  # the head's TPDOs came in the same exchange as the joints'
        t, _ = module.history("fault_flags")
        assert len(t) == robot.cycle, f"node {module.node.node_id}: {len(t)} cycles of {robot.cycle}"
    # The head's gyro, through its firmware, against the head link's true yaw rate: one count
    # of quantization and the gyro's noise apart, cycle by cycle, and the link did turn.
    t_gyro, gyro_z = head.history("gyro_z")
    t_true, yaw_rate = head.truth("yaw_rate_rad_s")
    _, in_gyro, in_true = np.intersect1d(t_gyro, t_true, return_indices=True)
    worst = float(np.max(np.abs(gyro_z[in_gyro] - yaw_rate[in_true])))
    assert np.max(np.abs(yaw_rate)) > 0.1, "the gait turns the snake's head"
    assert worst < 0.02, f"expected |gyro_z - head link yaw rate| < 0.02 rad/s, got {worst:.4f}"
    _, head_faults = head.history("fault_flags")
    assert not np.any(head_faults), f"the head faulted: {sorted(set(head_faults))}"
    session.close()
    trace = Trace.read(session.trace_path)
    assert trace.scalars[f"/modules/{rider.node_id}/fields/sensors/rail_current"]
    assert trace.scalars[f"/modules/{robot.joints[0].node.node_id}/fields/sensors/output_position"]


@pytest.mark.requirement("CHAIN_01")
def test_one_module_killed_mid_gait(make_robot) -> None:
    # Designed behaviour: the lost module is named with the cycle its TPDOs were due in, its
    # bridge is off from then on (the joint goes limp, its link still moves with the chain), and
    # the other modules keep following the wave: a module depends on the master, not on its
    # neighbours. Four modules: the same engine as eight, half the firmware processes to run.
    session = make_robot(4)
    robot = session.robot
    events = EventLog()
    robot.add_observer(events)
    GAIT.drive(robot)
    robot.at(1.0, lambda r: r.kill(3))
    robot.run(seconds=1.8)
    kill_cycle = 1000
    assert list(robot.lost) == [3]
    lost = robot.lost[3]
    assert lost.cycle == kill_cycle, lost
    assert "SIGKILL" in lost.reason, lost.reason
    assert events.events == [(kill_cycle, str(lost))]
    dead = robot.module(3)
    t, _ = dead.history("output_position")
    assert t[-1] == pytest.approx((kill_cycle - 1) * robot.period_s), "nothing from node 3 after it died"
    t, duty = dead.truth("applied_duty")
    assert np.all(duty[t > kill_cycle * robot.period_s] == 0.0), "the dead module's bridge is off"
    for node_id in robot.node_ids:
        if node_id != 3:
            error = tracking_error(robot, node_id, kill_cycle * robot.period_s)
            assert error <= TRACKING_TOLERANCE_RAD, f"node {node_id} after the loss: {error:.3f} rad"
    session.close()
    trace = Trace.read(session.trace_path)
    assert [text for text, _ in trace.texts["/events/robot"]] == [str(lost)]
    assert [text for text, _ in trace.texts["/modules/3/events/lost"]] == [str(lost)]


@pytest.mark.requirement("CHAIN_01")
def test_sixteen_modules_track_the_gait_and_one_lost_mid_gait_leaves_the_rest_tracking(make_robot) -> None:
    # The seed lab's snake: 16 modules (node ids 1..16) on one bus, two waves along the body.
    # As short as the physics allows: the wave's ramp and the chain's catching up (SETTLE_S),
    # a fifth of a second of tracking by all sixteen, then a middle module killed, and as long
    # again of the other fifteen tracking without it. Untraced: the trace of a robot is proved
    # by the eight-module gait.
    session = make_robot(16, trace=False)
    robot = session.robot
    assert robot.node_ids == tuple(range(1, 17))
    events = EventLog()
    robot.add_observer(events)
    GAIT.drive(robot)
    kill_s, end_s, victim = SETTLE_S + 0.2, SETTLE_S + 0.4, 9
    robot.at(kill_s, lambda r: r.kill(victim))
    robot.run(seconds=end_s)
    kill_cycle = round(kill_s / robot.period_s)
    before = {n: tracking_error(robot, n, SETTLE_S, kill_s - robot.period_s) for n in robot.node_ids}
    after = {n: tracking_error(robot, n, kill_s) for n in robot.node_ids if n != victim}
    print(
        f"\n16 modules, max |commanded - measured| in [{SETTLE_S:g}, {kill_s:g}) s: "
        + ", ".join(f"{n}: {e:.4f}" for n, e in before.items())
        + f"; after node {victim} was lost: "
        + ", ".join(f"{n}: {e:.4f}" for n, e in after.items())
    )
    for node_id, error in before.items():
        assert error <= TRACKING_TOLERANCE_RAD, f"node {node_id} tracks within {error:.3f} rad"
    # Designed behaviour: the lost module is named with the cycle its TPDOs were due in, its
    # bridge is off from then on (the joint goes limp, its link still moves with the chain), and
    # the other modules keep following the wave: a module depends on the master, not on its
    # neighbours.
    assert list(robot.lost) == [victim]
    lost = robot.lost[victim]
    assert lost.cycle == kill_cycle, lost
    assert "SIGKILL" in lost.reason, lost.reason
    assert events.events == [(kill_cycle, str(lost))]
    dead = robot.module(victim)
    t, _ = dead.history("output_position")
    assert t[-1] == pytest.approx((kill_cycle - 1) * robot.period_s), "nothing from the dead node"
    t, duty = dead.truth("applied_duty")
    assert np.all(duty[t > kill_cycle * robot.period_s] == 0.0), "the dead module's bridge is off"
    for node_id, error in after.items():
        assert error <= TRACKING_TOLERANCE_RAD, f"node {node_id} after the loss: {error:.3f} rad"
    # The encoders report what the mechanics did, for every module still alive.
    for node_id in robot.node_ids:
        if node_id != victim:
            _, measured = robot.module(node_id).history("output_position")
            _, truth = robot.module(node_id).truth("load_angle")
            assert abs(measured[-1] - truth[-2]) < 0.01, f"node {node_id}: {measured[-1]} vs {truth[-2]}"


@pytest.mark.requirement("PROT_08")
def test_master_heartbeat_lost_every_module_safe_within_the_consumer_time(make_robot) -> None:
    master = MasterHeartbeat()
    session = make_robot(4, master=master)
    robot = session.robot
    GAIT.drive(robot)
    robot.run(seconds=0.5)
    last_heartbeat_cycle = robot.cycle - master.period_ms  # sent every period_ms cycles at 1 ms
    assert robot.cycle % master.period_ms == 0
    robot.stop_master_heartbeat()
    robot.run(seconds=0.2)
    deadline = last_heartbeat_cycle + master.consumer_ms + 1  # the consumer's time, in cycles
    for node_id in robot.node_ids:
        module = robot.module(node_id)
        lost = [e for e in module.emcy if e.code == EmcyCode.HEARTBEAT_ERROR]
        assert len(lost) == 1, f"node {node_id}: EMCYs {module.emcy}"
        assert last_heartbeat_cycle + master.consumer_ms - 1 <= lost[0].cycle <= deadline, lost[0]
        assert FaultFlags.MASTER_HEARTBEAT_LOST in FaultFlags(int(module.read("fault_flags")))
        assert module.read("safe_state") == 1
        t, duty = module.history("motor_duty")
        assert np.all(duty[t >= deadline * robot.period_s] == 0), f"node {node_id} still drives"


@pytest.mark.requirement("ID_01")
def test_two_modules_with_one_node_id_are_refused(make_robot, scenario_dir: Path) -> None:
    with pytest.raises(ValueError, match=r"node id 2 \(0x02\) is given to two modules"):
        make_robot(node_ids=[1, 2, 2])
    assert not list(scenario_dir.glob("firmware-*.log")), "nothing may start"


def test_scan_lists_every_module_with_its_identity(make_robot, private_bus) -> None:
    make_robot(4, trace=False, start=False)
    scan = run_hilrig(private_bus, "scan", "--listen", "3", "--sdo-timeout", "5")
    assert scan.returncode == 0, scan.stderr
    node = TABLE.board.node
    rows = [line.split() for line in scan.stdout.splitlines()[1:]]
    assert rows == [
        [
            f"0x{node_id:02X}",
            "pre_operational",
            node.device_name,
            f"0x{node.vendor_id:08X}",
            f"0x{node.product_code:08X}",
            f"0x{node.revision:08X}",
        ]
        for node_id in (1, 2, 3, 4)
    ]
