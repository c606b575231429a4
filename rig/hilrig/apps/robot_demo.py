"""The modular robot, end to end: N joint modules (the firmware started N times) on one private
bus, the chain's mechanics from MuJoCo, a travelling-wave gait (or a scenario file), a summary and
a trace with the chain in 3D. `hilrig sim --modules N` and `make run ROBOT=N` call `run_robot`::

    summary = run_robot(RobotOptions(robot_run(Path("out/robot"), modules=8)))
    print(format_robot_summary(summary))

A scenario file defines `def scenario(robot): ...` and drives the `hilrig.engine.robot.Robot` itself.
"""

from __future__ import annotations

import runpy
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from boardproto.table import FULL_PDO_PROFILE
from hilrig.apps.demo import Progress, RunAbortedError, ScenarioFileError
from hilrig.apps.gait import TravellingWave
from hilrig.engine.robot import Robot
from hilrig.errors import FirmwareError, LockstepError
from hilrig.session.builder import hil_session
from hilrig.session.netns import require_private_buses
from hilrig.session.run import BOOT_TIMEOUT_S, FirmwareRun, RigRun, RobotRun, RunDescription, TraceRun
from hilrig.table import RigTable

RobotScenario = Callable[[Robot], object]
GAIT_SECONDS = 4.0
"""Default length of the gait: two periods of the 0.5 Hz wave."""
PROGRESS_EVERY_S = 0.5
"""A progress line per this much simulated time."""
SETTLE_S = TravellingWave().ramp_s + 0.5
"""Tracking errors skip the wave's ramp and the half second after it (the chain catches up)."""


def robot_run(out_dir: Path, modules: int | Sequence[int] = 8) -> RunDescription:
    """The robot demo's run: `modules` joint modules in lockstep on one private bus, seed 1."""
    return RunDescription(
        TraceRun(out_dir),
        firmware=FirmwareRun(boot_timeout_s=BOOT_TIMEOUT_S),
        rig=RigRun(seed=1, sdo_timeout_s=5.0),
        robot=RobotRun(modules),
    )


@dataclass(frozen=True)
class RobotOptions:
    """What the robot demo adds to its run (`robot_run`, or one from the command line)."""

    run: RunDescription
    seconds: float = GAIT_SECONDS
    scenario_file: Path | None = None


@dataclass(frozen=True)
class ModuleSummary:
    node_id: int
    max_tracking_error_rad: float | None
    peak_duty: float
    lost: str | None


@dataclass(frozen=True)
class RobotSummary:
    cycles: int
    simulated_s: float
    cycling_s: float
    wall_s: float
    modules: tuple[ModuleSummary, ...]
    head_travel_m: float
    out_dir: Path
    trace: Path | None
    viewer_url: str | None
    bus_load: tuple[str, ...] = ()
    """What a real 1 Mbit/s bus would carry for these modules at this rate (`robot_load_line`):
    one line per PDO profile of the table, the one in use marked."""


def load_robot_scenario(path: Path) -> RobotScenario:
    try:
        namespace = runpy.run_path(str(path))
    except (OSError, SyntaxError) as error:
        raise ScenarioFileError(f"scenario {path}: {error}") from error
    scenario = namespace.get("scenario")
    if not callable(scenario):
        raise ScenarioFileError(f"scenario {path}: define `def scenario(robot): ...`")
    return scenario  # type: ignore[no-any-return]


def gait_scenario(seconds: float, progress: Progress) -> RobotScenario:
    def scenario(robot: Robot) -> None:
        gait = TravellingWave()
        progress(
            f"sim: travelling wave, {gait.amplitude_rad:g} rad at {gait.frequency_hz:g} Hz, "
            f"{gait.phase_per_joint_rad:.3f} rad between joints, for {seconds:g} s"
        )
        gait.drive(robot)
        end = robot.t + seconds
        while robot.t < end - 1e-9:  # in chunks, to show progress: a robot is slow in the VM
            chunk = min(PROGRESS_EVERY_S, end - robot.t)
            started = time.monotonic()
            robot.run(seconds=chunk)
            rate = chunk / robot.period_s / max(time.monotonic() - started, 1e-9)
            progress(f"sim: t = {robot.t:.2f} s of {end:g} s ({rate:.0f} cycles/s)")

    return scenario


def run_robot(options: RobotOptions, progress: Progress = print) -> RobotSummary:
    """The robot session (`hilrig.session.builder`, `modules=`), the scenario, the summary."""
    require_private_buses(
        "the robot", "run `make run ROBOT=8`, or `tools/with-vcan -- .venv/bin/hilrig sim --modules 8`"
    )
    scenario = (
        load_robot_scenario(options.scenario_file)
        if options.scenario_file is not None
        else gait_scenario(options.seconds, progress)
    )
    run = options.run
    assert run.robot is not None, "a robot's run names its modules (RunDescription.robot)"
    table = RigTable.load()
    started = time.monotonic()
    modules = run.robot.modules
    count = modules if isinstance(modules, int) else len(modules)
    progress(
        f"sim: starting {count} x {run.firmware.executable.name} (lockstep, {run.rig.cycle_us(table)} us) "
        "on one private bus, the chain's mechanics from MuJoCo"
    )
    if run.trace.trace is not False:
        progress("sim: tracing to Rerun (importing rerun-sdk takes a while in the VM)")
    with hil_session(run, table=table) as session:
        robot = session.robot
        assert robot is not None
        progress(f"sim: modules {', '.join(f'0x{n:02X}' for n in robot.node_ids)} operational")
        head_start, _ = robot.chain.poses()
        cycling_started = time.monotonic()
        try:
            scenario(robot)
        except (FirmwareError, LockstepError) as error:
            first_line = str(error).splitlines()[0].rstrip(";: ")
            raise RunAbortedError(f"{first_line}; {session.evidence()}") from error
        cycling_s = time.monotonic() - cycling_started
        head_end, _ = robot.chain.poses()
        modules = tuple(_module_summary(robot, node_id) for node_id in robot.node_ids)
        viewer_url = session.tracer.web_url if session.tracer is not None else None
        cycles = robot.cycle
        simulated_s = robot.t
        bus_load = _bus_load(robot, run.robot)
    return RobotSummary(
        cycles=cycles,
        simulated_s=simulated_s,
        cycling_s=cycling_s,
        wall_s=time.monotonic() - started,
        modules=modules,
        head_travel_m=float(np.linalg.norm(head_end[0] - head_start[0])),
        out_dir=run.out_dir,
        trace=session.trace_path,
        viewer_url=viewer_url,
        bus_load=bus_load,
    )


def _bus_load(robot: Robot, described: RobotRun) -> tuple[str, ...]:
    """The bus load lines of the summary, one per PDO profile of the table: the modules run the
    firmware's default mapping (profile full: the session writes none); the others (lean: made
    to fit a real bus) show what it would take."""
    from hilrig.apps.busload import robot_load_line

    table = RigTable.load().board
    master_ms = described.master.period_ms if described.master is not None else None
    return tuple(
        robot_load_line(
            table,
            robot.node_ids,
            1e6 / robot.period_us,
            profile=profile.name,
            master_heartbeat_ms=master_ms,
        )
        + (" (in use)" if profile.name == FULL_PDO_PROFILE else "")
        for profile in table.pdo_profiles
    )


def _module_summary(robot: Robot, node_id: int) -> ModuleSummary:
    module = robot.module(node_id)
    t_cmd, commanded = module.sent("position_setpoint")
    t_meas, measured = module.history("output_position")
    times, in_cmd, in_meas = np.intersect1d(t_cmd, t_meas, return_indices=True)
    settled = times >= SETTLE_S
    error = None
    if settled.any():
        error = float(np.max(np.abs(commanded[in_cmd][settled] - measured[in_meas][settled])))
    _, duty = module.truth("applied_duty")
    lost = robot.lost.get(node_id)
    return ModuleSummary(
        node_id, error, float(np.max(np.abs(duty))) if len(duty) else 0.0, str(lost) if lost else None
    )


def format_robot_summary(summary: RobotSummary) -> str:
    rate = f"{summary.cycles / summary.cycling_s:.0f} cycles/s; " if summary.cycling_s > 0 else ""
    rows = [
        (
            "simulated",
            f"{summary.cycles} cycles = {summary.simulated_s:.3f} s of {len(summary.modules)} modules in "
            f"{summary.cycling_s:.1f} s wall ({rate}{summary.wall_s:.1f} s with start-up)",
        ),
    ]
    for i, module in enumerate(summary.modules):
        error = "-" if module.max_tracking_error_rad is None else f"{module.max_tracking_error_rad:.4f} rad"
        text = f"node 0x{module.node_id:02X}: max |commanded - measured| {error} after {SETTLE_S:g} s, "
        text += f"peak duty {module.peak_duty:.2f}"
        if module.lost:
            text += f"; {module.lost}"
        rows.append(("joints" if i == 0 else "", text))
    rows += [(("real bus load" if i == 0 else ""), line) for i, line in enumerate(summary.bus_load)]
    rows += [
        ("head travelled", f"{summary.head_travel_m:.3f} m (MuJoCo, start to end)"),
        ("bus log", f"{summary.out_dir / 'bus.log'} (`hilrig replay ... --decode`)"),
        ("firmware logs", f"{summary.out_dir}/firmware-<node id>.log"),
    ]
    if summary.trace is not None:
        rows += [
            ("trace (Rerun)", f"{summary.trace} (modules under /modules/<id>, the chain in 3D: /robot)"),
            ("open it with", f"hilrig view {summary.trace} --dashboard robot"),
        ]
    if summary.viewer_url is not None:
        rows.append(("live web viewer", summary.viewer_url))
    width = max(len(name) for name, _ in rows)
    return "\n".join(f"{name.ljust(width)}  {value}" for name, value in rows)
