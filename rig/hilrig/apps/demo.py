"""The demo joint, end to end: the firmware in lockstep on a private bus, the rig's physics,
a velocity then a torque profile (or a scenario file), and a summary.

`make run` and `hilrig sim` both call `run_demo`. Needs root and a kernel with vcan (natively,
or inside the micro-VM of `tools/with-vcan`)::

    summary = run_demo(DemoOptions(demo_run(Path("out/demo"))))
    print(format_summary(summary))

With `demo_run(out_dir, board=BoardInterface(...))` the same profiles run in real time against a board (or a
free-running firmware) on that interface: no firmware is started, the rig sends SYNC every
period. `live` sinks stream the trace to a viewer while it runs, beside out_dir/trace.rrd.

A scenario file defines `def scenario(rig): ...` and drives the `Rig` itself (rig.set,
rig.run, rig.at...); the summary is computed from what it ran.

Another plant or board: `plant` is a plant factory (`(params, seed) -> Plant`, e.g.
`hilrig.plants.fmu.fmu_factory`) and `table` the board's table. The velocity and torque profiles
and the joint's rows of the summary are the demo joint's: another table needs a scenario file,
and its summary has the run's rows only.
"""

from __future__ import annotations

import dataclasses
import runpy
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hilrig.engine.rig import Rig, TimingMode
from hilrig.errors import FirmwareError, LockstepError, RealTimeError, RigError
from hilrig.plants import JointParams
from hilrig.plants.joint import SPRING_STIFFNESS
from hilrig.session.baremetal import QEMU_VIRT
from hilrig.session.builder import hil_session
from hilrig.session.faults import FaultEvent, FaultInjector, FaultPlan
from hilrig.session.netns import require_private_buses
from hilrig.session.run import (
    BOOT_TIMEOUT_S,
    BoardInterface,
    BusRun,
    FirmwareRun,
    RigRun,
    RunDescription,
    TraceRun,
)
from hilrig.table import BOARD_TABLE, ControlMode, RigTable
from hilrig.wire.node import EmcyRecord

Scenario = Callable[[Rig], object]
Progress = Callable[[str], None]

SETTLE_S = 0.2
"""Tracking errors skip this long after each setpoint or mode change (the step response)."""
DEFAULT_POLL_EVERY = 250
"""Cycles between SDO reads of the fields a dashboard plots but no PDO carries (4 Hz at 1 kHz).
Each read is a round trip between two cycles, dear in the micro-VM: the rarer, the closer `make
run` keeps to its pace without polling."""


class ScenarioFileError(RigError, ValueError):
    """A --scenario file that cannot be used (the message says why)."""


class RunAbortedError(RigError):
    """The firmware died or stopped answering mid-run; the message names the cycle and where
    the evidence is (trace, bus log, firmware log), all of it written whole."""


@dataclass(frozen=True)
class Step:
    """Hold `value` on `setpoint` for `seconds` of simulation time."""

    setpoint: str
    value: float
    seconds: float


VELOCITY_PROFILE = (
    Step("velocity_setpoint", 3.0, 0.6),
    Step("velocity_setpoint", -2.0, 0.6),
    Step("velocity_setpoint", 0.0, 0.3),
)
"""Gearbox-side velocity [rad/s]: up, reverse, stop."""
TORQUE_PROFILE = (
    Step("torque_setpoint", 0.5, 0.4),
    Step("torque_setpoint", 2.5, 0.4),
    Step("torque_setpoint", 1.0, 0.4),
    Step("torque_setpoint", 3.0, 1.5),
    Step("torque_setpoint", 0.0, 0.3),
)
"""Spring torque [N*m] against the demo's viscous load: steps the spring-constant estimator can
learn from (quasi-static motion at several deflections), the last high one held until the hot
winding passes thermal_warning_c and the firmware derates the drive (the thermal dashboard)."""
DEMO_AMBIENT_C = 79.0
"""The demo joint sits in a hot enclosure: its winding starts a kelvin below the firmware's
thermal warning (80 degC by default), so the torque profile shows the derate within seconds."""


def demo_params() -> JointParams:
    """The demo joint: a load with strong viscous friction (constant torque gives a steady speed,
    so torque steps are quasi-static), a winding that heats in seconds, not minutes, in a hot
    enclosure (`DEMO_AMBIENT_C`)."""
    return dataclasses.replace(
        JointParams.fast_thermal(),
        load_viscous_friction_nm_s_per_rad=1.0,
        ambient_temperature_c=DEMO_AMBIENT_C,
    )


def demo_run(out_dir: Path, board: BoardInterface | None = None) -> RunDescription:
    """The demo's run: the demo joint (`demo_params`) with seed 1 in lockstep on a private bus;
    with `board`, the rig in real time against it (no firmware started, its heartbeat awaited
    `BOARD_SILENT_S`)."""
    run = RunDescription(
        TraceRun(out_dir),
        firmware=FirmwareRun(boot_timeout_s=BOOT_TIMEOUT_S),
        rig=RigRun(params=demo_params(), seed=1, sdo_timeout_s=1.0),
    )
    if board is None:
        return run
    return run.replace(
        bus=BusRun(board=board),
        firmware=dataclasses.replace(run.firmware, boot_timeout_s=BOARD_SILENT_S),
        rig=dataclasses.replace(run.rig, timing=TimingMode.REALTIME),
    )


@dataclass(frozen=True)
class DemoOptions:
    """What the demo adds to its run (`demo_run`, or one from the command line)."""

    run: RunDescription
    scenario_file: Path | None = None
    faults: FaultPlan = field(default_factory=FaultPlan)
    poll_every: int = DEFAULT_POLL_EVERY
    """With a trace: every how many cycles the fields a dashboard plots but no PDO carries are
    read over SDO into it (0: never)."""
    table: RigTable | None = None
    """The board's table; None: the demo joint's."""


@dataclass(frozen=True)
class DemoSummary:
    cycles: int
    simulated_s: float
    wall_s: float
    """From the command's start to the end of the scenario (start-up of the session included)."""
    cycling_s: float
    """The scenario alone: the lockstep cycles, without the session's start-up."""
    velocity_rms_error_rad_s: float | None
    torque_rms_error_nm: float | None
    spring_constant_estimate: float | None
    """None (and the joint's other rows): a run on another board's table."""
    spring_constant_confidence: float | None
    spring_constant_true: float | None
    peak_temperature_reported_c: float | None
    peak_temperature_true_c: float | None
    fault_flags: int
    safe_state: bool
    emcy: tuple[EmcyRecord, ...]
    bus_log: Path
    firmware_log: Path | None
    """None: a board's run (no firmware process of the rig's)."""
    frames_logged: int
    trace: Path | None = None
    faults: tuple[FaultEvent, ...] = ()
    viewer_url: str | None = None
    """The page of the web viewer serving this run's trace (a `web` live sink)."""
    bus_timing: str | None = None
    """On the timed bus: what it carried (`BusTimeline.describe`)."""
    firmware_platform: str = "linux"
    """Where the firmware ran (hilrig.session.baremetal.FIRMWARE_PLATFORMS)."""


def load_scenario(path: Path) -> Scenario:
    """`scenario(rig)` from a Python file."""
    try:
        namespace = runpy.run_path(str(path))
    except OSError as error:
        raise ScenarioFileError(f"cannot read scenario {path}: {error.strerror}") from error
    scenario = namespace.get("scenario")
    if not callable(scenario):
        raise ScenarioFileError(f"{path} defines no function `scenario(rig)`")
    return scenario


def run_profile(rig: Rig, mode: int, steps: tuple[Step, ...], progress: Progress, what: str) -> None:
    rig.set("control_mode", mode)
    for step in steps:
        rig.set(step.setpoint, step.value)
        progress(f"sim: t = {rig.t:.2f} s  {what}: {step.setpoint} = {step.value:g} for {step.seconds:g} s")
        rig.run(seconds=step.seconds)


def default_scenario(progress: Progress) -> Scenario:
    def scenario(rig: Rig) -> None:
        run_profile(rig, ControlMode.VELOCITY, VELOCITY_PROFILE, progress, "velocity profile")
        run_profile(rig, ControlMode.TORQUE, TORQUE_PROFILE, progress, "torque profile")
        rig.set("control_mode", ControlMode.DISABLED)
        rig.run(cycles=1)

    return scenario


BOARD_SILENT_S = 5.0
"""How long `run_demo` waits for a board's heartbeat (or boot-up) before it asks over SDO: a
board is already running, so a silent bus is said within seconds, not after the VM's hang guard."""


def run_demo(options: DemoOptions, progress: Progress = print) -> DemoSummary:
    """Firmware + rig in lockstep on a private bus (`hilrig.session.builder`), or the rig in real time
    against `options.board`; the bus log goes to out_dir/bus.log."""
    if options.run.bus.board is None:
        require_private_buses(
            "the simulation", "run `make run`, or `tools/with-vcan -- .venv/bin/hilrig sim`"
        )
    table = options.table if options.table is not None else RigTable.load()
    if options.scenario_file is None and not table.is_default_board:
        raise ScenarioFileError(
            f"the demo's profiles drive the demo joint, not {table.board.source.name}'s board: "
            "pass a scenario file defining `def scenario(rig): ...`"
        )
    scenario = (
        load_scenario(options.scenario_file)
        if options.scenario_file is not None
        else default_scenario(progress)
    )
    run = options.run
    board = run.bus.board
    out = run.out_dir
    node_id = run.node_id(table)
    period_us = run.rig.cycle_us(table)
    tracing = run.trace.trace is not False
    started = time.monotonic()
    if tracing:
        progress("sim: tracing to Rerun (importing rerun-sdk takes a while in the VM)")
        if run.trace.live:
            progress("sim: streaming the trace live to " + ", ".join(map(str, run.trace.live)))
    if board is None:
        executable = run.firmware.image if run.firmware.platform == QEMU_VIRT else run.firmware.executable
        progress(
            f"sim: starting {executable.name} (node 0x{node_id:02X}, lockstep, "
            f"{period_us} us) on a private bus"
        )
    else:
        progress(
            f"sim: node 0x{node_id:02X} on {board.interface} {board.channel}, "
            f"real time, SYNC every {period_us} us; waiting up to {BOARD_SILENT_S:g} s for "
            "its heartbeat"
        )
    with hil_session(run, table=table) as session:
        rig = session.rig
        assert rig is not None
        injector: FaultInjector | None = None
        if options.faults:
            injector = FaultInjector(
                rig,
                options.faults,
                firmware=session.firmware,
                boot_timeout_s=BOOT_TIMEOUT_S,
                on_event=lambda e: progress(f"sim: t = {e.time_s:.3f} s  fault {e.text}"),
            )
            injector.install()
        if tracing and options.poll_every > 0:
            from hilrig.observe.blueprints import dashboard_fields

            slow = rig.in_no_pdo(dashboard_fields(table))
            if slow:
                rig.poll_over_sdo(slow, every_cycles=options.poll_every)
                every = options.poll_every
                progress(f"sim: reading {', '.join(slow)} over SDO every {every} cycles (in no PDO)")
        progress("sim: node operational, running the scenario")
        cycling_started = time.monotonic()
        try:
            scenario(rig)
        except (FirmwareError, LockstepError, RealTimeError) as error:
            first_line = str(error).splitlines()[0].rstrip(";: ")
            raise RunAbortedError(f"{first_line}; {session.evidence()}") from error
        cycling_s = time.monotonic() - cycling_started
        summary = summarize(rig, table, started, out, 0, cycling_s)
        if injector is not None:
            summary = dataclasses.replace(summary, faults=tuple(injector.log))
        recorder = session.recorder
        viewer_url = session.tracer.web_url if session.tracer is not None else None
    summary = dataclasses.replace(
        summary,
        frames_logged=recorder.frames if recorder is not None and recorder.frames is not None else 0,
        firmware_log=out / "firmware.log" if board is None else None,
        viewer_url=viewer_url,
        firmware_platform=run.firmware.platform,
    )
    if session.trace_path is not None:
        summary = dataclasses.replace(summary, trace=out / "trace.rrd")
    return summary


def _step_values(times: np.ndarray, change_t: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Value of a sparsely sent signal (sent at change_t) at each of `times` (NaN before)."""
    index = np.searchsorted(change_t, times, side="right") - 1
    result = np.full(times.shape, np.nan)
    valid = index >= 0
    result[valid] = values[index[valid]]
    return result


def _rms_tracking(rig: Rig, mode: int, setpoint: str, measured: str, scale: float) -> float | None:
    """RMS of setpoint - measured*scale over the cycles in `mode`, settled after each change."""
    t_sp, sp = rig.sent(setpoint)
    t_meas, meas = rig.history(measured)
    t_mode, modes = rig.sent("control_mode")
    if not len(t_sp) or not len(t_meas) or not len(t_mode):
        return None
    meas_at = np.interp(t_sp, t_meas, meas.astype(float) * scale, left=np.nan, right=np.nan)
    mode_at = _step_values(t_sp, t_mode, modes.astype(float))
    changes = np.concatenate([t_sp[1:][np.diff(sp) != 0], t_mode])
    last_change = _step_values(t_sp, np.sort(changes), np.sort(changes))
    settled = np.isnan(last_change) | (t_sp - np.nan_to_num(last_change) >= SETTLE_S)
    mask = (mode_at == mode) & settled & ~np.isnan(meas_at)
    if not mask.any():
        return None
    return float(np.sqrt(np.mean((sp[mask] - meas_at[mask]) ** 2)))


def _peak(rig: Rig, name: str) -> float | None:
    _, values = rig.history(name)
    return float(np.max(values)) if len(values) else None


def _peak_truth(rig: Rig, name: str) -> float | None:
    """The peak of a truth quantity, None when the plant has no such truth (another plant's)."""
    try:
        _, values = rig.truth(name)
    except (KeyError, ValueError, RigError):
        return None
    return float(np.max(values)) if len(values) else None


def summarize(
    rig: Rig, table: RigTable, started: float, out: Path, frames: int, cycling_s: float
) -> DemoSummary:
    # The summary's SDO reads come after the run, off the timed bus (an overloaded one would
    # never carry them); what the bus carried is said first.
    timeline = rig.leave_timed_bus()
    bus_timing = None if timeline is None or rig.bitrate is None else timeline.describe(rig.bitrate)
    names = {f.name for f in table.board.fields}
    flags = rig.history("fault_flags")[1] if "fault_flags" in names else np.array([])
    safe = rig.history("safe_state")[1] if "safe_state" in names else np.array([])
    joint: dict[str, float | None] = dict.fromkeys(
        (
            "velocity_rms_error_rad_s",
            "torque_rms_error_nm",
            "spring_constant_estimate",
            "spring_constant_confidence",
            "spring_constant_true",
            "peak_temperature_reported_c",
            "peak_temperature_true_c",
        )
    )
    if table.is_default_board:
        gear_ratio = float(rig.read("gear_ratio"))
        stiffness = rig.plant.truth_parameters().get(SPRING_STIFFNESS)
        joint.update(
            velocity_rms_error_rad_s=_rms_tracking(
                rig, ControlMode.VELOCITY, "velocity_setpoint", "motor_velocity", 1.0 / gear_ratio
            ),
            torque_rms_error_nm=_rms_tracking(
                rig, ControlMode.TORQUE, "torque_setpoint", "joint_torque", 1.0
            ),
            spring_constant_estimate=float(rig.read("spring_constant_estimate")),
            spring_constant_confidence=float(rig.read("spring_constant_confidence")),
            spring_constant_true=stiffness,
            peak_temperature_reported_c=_peak(rig, "winding_temperature"),
            peak_temperature_true_c=_peak_truth(rig, "winding_temperature"),
        )
    return DemoSummary(
        cycles=rig.cycle,
        simulated_s=rig.t,
        wall_s=time.monotonic() - started,
        cycling_s=cycling_s,
        **joint,  # type: ignore[arg-type]
        fault_flags=int(np.bitwise_or.reduce(flags.astype(np.int64))) if len(flags) else 0,
        safe_state=bool(len(safe) and np.max(safe) > 0),
        emcy=tuple(rig.emcy),
        bus_log=out / "bus.log",
        firmware_log=out / "firmware.log",
        frames_logged=frames,
        bus_timing=bus_timing,
    )


def _fmt(value: float | None, unit: str, digits: str = ".3g") -> str:
    return "-" if value is None else f"{value:{digits}} {unit}"


def _rate(cycles: int, seconds: float) -> str:
    return f"{cycles / seconds:.0f} cycles/s; " if seconds > 0 else ""


def _joint_rows(summary: DemoSummary) -> list[tuple[str, str]]:
    """The demo joint's rows of the summary (none on another board's table)."""
    if summary.spring_constant_estimate is None:
        return []
    true_k = _fmt(summary.spring_constant_true, "true", ".4g")
    return [
        (
            "velocity tracking error",
            _fmt(summary.velocity_rms_error_rad_s, "rad/s RMS")
            + f" (setpoint vs motor_velocity / gear_ratio, {SETTLE_S:g} s after each step)",
        ),
        (
            "torque tracking error",
            _fmt(summary.torque_rms_error_nm, "N*m RMS")
            + f" (setpoint vs joint_torque, {SETTLE_S:g} s after each step)",
        ),
        (
            "spring constant",
            f"{summary.spring_constant_estimate:.4g} N*m/rad estimated "
            f"(confidence {summary.spring_constant_confidence or 0.0:.2f}), {true_k}",
        ),
        (
            "peak winding temperature",
            _fmt(summary.peak_temperature_reported_c, "degC", ".4g")
            + f" reported, {_fmt(summary.peak_temperature_true_c, 'degC', '.4g')} true",
        ),
    ]


def format_summary(summary: DemoSummary) -> str:
    """The summary table people read after `make run`."""
    faults = "none"
    if summary.emcy or summary.fault_flags or summary.safe_state:
        names = BOARD_TABLE.bitset("fault_flags").label(summary.fault_flags)
        parts = [f"fault_flags 0x{summary.fault_flags:X} ({names})"] if summary.fault_flags else []
        if summary.safe_state:
            parts.append("safe state entered")
        parts += [str(record) for record in summary.emcy[:5]]
        if len(summary.emcy) > 5:
            parts.append(f"... {len(summary.emcy) - 5} more EMCY")
        faults = "; ".join(parts)
    rows = [
        (
            "simulated",
            f"{summary.cycles} cycles = {summary.simulated_s:.3f} s in {summary.cycling_s:.1f} s wall "
            f"({_rate(summary.cycles, summary.cycling_s)}{summary.wall_s:.1f} s with start-up)",
        ),
        *_joint_rows(summary),
        ("faults", faults),
        *((("timed bus", summary.bus_timing),) if summary.bus_timing is not None else ()),
        *(
            ("fault injected" if i == 0 else "", f"t = {e.time_s:.3f} s  {e.text}")
            for i, e in enumerate(summary.faults)
        ),
        (
            "bus log",
            f"{summary.bus_log} ({summary.frames_logged} frames; `hilrig replay {summary.bus_log} --decode`)",
        ),
    ]
    if summary.firmware_log is not None:
        rows.append(("firmware log", f"{summary.firmware_log} (platform {summary.firmware_platform})"))
    if summary.trace is not None:
        rows += [
            ("trace (Rerun)", str(summary.trace)),
            ("open it with", f"hilrig view {summary.trace}   (--dashboard tuning, --web: browser)"),
        ]
    if summary.viewer_url is not None:
        rows.append(("live web viewer", summary.viewer_url))
    width = max(len(name) for name, _ in rows)
    return "\n".join(f"{name.ljust(width)}  {value}" for name, value in rows)
