"""`hilrig sim`: the demo joint against the real firmware, in lockstep, with a summary."""

from __future__ import annotations

import argparse
import dataclasses
import signal
from pathlib import Path
from typing import TYPE_CHECKING

from hilrig.cli.common import (
    Command,
    UsageError,
    add_bus_options,
    add_table_option,
    bus_config,
    eds_path,
    existing_file,
    live_sink,
    progress,
)
from hilrig.cli.files import output_folder, sniff_toml
from hilrig.resources import FIRMWARE_HINT
from hilrig.session.baremetal import FIRMWARE_PLATFORMS, LINUX, QEMU_VIRT, default_image
from hilrig.session.run import RunDescription, TraceRun
from hilrig.table import RigTable

if TYPE_CHECKING:
    from collections.abc import Sequence

    from hilrig.observe.sinks import TraceSink
    from hilrig.session.builder import PlantFactory
    from hilrig.session.faults import FaultSpec


def fault_spec(text: str) -> FaultSpec:
    from hilrig.session.faults import FaultSpec, FaultSpecError

    try:
        return FaultSpec.parse(text)
    except FaultSpecError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def modules_spec(text: str) -> int | tuple[int, ...]:
    """--modules: a count (8: node ids 1..8) or node ids (1,2,5 or 0x01,0x02)."""
    from hilrig.engine.robot import module_ids

    try:
        spec: int | tuple[int, ...] = (
            int(text) if "," not in text else tuple(int(part, 0) for part in text.split(","))
        )
        if isinstance(spec, int) and spec < 1:
            raise ValueError(f"expected at least 1 module, got {spec}")
        module_ids(spec)
    except ValueError as error:
        raise argparse.ArgumentTypeError(
            f"{error} (expected a count like 8, or node ids like 1,2,5)"
        ) from None
    return spec


def configure(parser: argparse.ArgumentParser) -> None:
    from hilrig.apps.demo import DEFAULT_POLL_EVERY
    from hilrig.session.faults import FAULT_SYNTAX_HELP  # the fault models need numpy: only for `sim`

    parser.add_argument(
        "--out",
        type=output_folder,
        default=Path("out/demo"),
        metavar="DIR",
        help="where bus.log, firmware.log and summary.txt go (default: out/demo)",
    )
    parser.add_argument(
        "--scenario",
        type=existing_file(
            "scenario", "pass a .py file that defines `def scenario(rig): ...`", suffixes=(".py",)
        ),
        metavar="FILE.py",
        help="run `scenario(rig)` from this file instead of the velocity and torque profiles "
        "(with --modules: `scenario(robot)` instead of the gait)",
    )
    robot = parser.add_argument_group("a modular robot (several modules on one bus)")
    robot.add_argument(
        "--modules",
        type=modules_spec,
        default=None,
        metavar="N|IDS",
        help="run a robot: the firmware started N times (node ids 1..N) or with these node ids "
        "(1,2,5) on one private bus, one SYNC for all, the chain's mechanics from MuJoCo (a snake "
        "on the ground), a travelling-wave gait; the trace shows each module under "
        "/modules/<id> and the chain in 3D",
    )
    robot.add_argument(
        "--seconds",
        type=float,
        default=None,
        metavar="S",
        help="with --modules: how long the gait runs, in simulation time (default: 4)",
    )
    RunDescription.add_arguments(parser, seed=1)  # every run option: -n, --firmware, --eds too
    parser.add_argument(
        "--firmware-platform",
        choices=FIRMWARE_PLATFORMS,
        default=LINUX,
        help="where the firmware runs: linux (the firmware process, default) or qemu-virt (the "
        "bare-metal image under qemu-system-arm; --firmware then names the image, default "
        "build/qemu-virt/bin/joint-firmware-virt.elf from `make baremetal`)",
    )
    parser.add_argument(
        "--fault",
        action="append",
        type=fault_spec,
        default=[],
        metavar="SPEC",
        help="inject a fault (repeatable): " + FAULT_SYNTAX_HELP + "; e.g. drop:thermistor_adc@0.5+0.2",
    )
    plant = parser.add_argument_group("another plant (an FMU) or board (docs/fmu.md)")
    plant.add_argument(
        "--plant",
        type=existing_file("FMU", "pass an FMI 2.0/3.0 co-simulation .fmu", suffixes=(".fmu",)),
        default=None,
        metavar="MODEL.fmu",
        help="run this FMU as the board's plant instead of the demo joint's physics (needs "
        "--plant-map; pip install 'hilrig[fmu]')",
    )
    plant.add_argument(
        "--plant-map",
        type=existing_file(
            "plant map",
            "pass the TOML map of the FMU to the table (docs/fmu.md)",
            suffixes=(".toml",),
            sniff=sniff_toml,
        ),
        default=None,
        metavar="MAP.toml",
        help="how the FMU's variables meet the table's HIL I/O, checked at start (docs/fmu.md); "
        "a map that names its `fmu` needs no --plant",
    )
    add_table_option(plant)
    trace = parser.add_argument_group("trace (Rerun)")
    trace.add_argument(
        "--viewer",
        action="append",
        type=live_sink,
        default=None,
        metavar="WHERE",
        help="also stream the trace live while the run goes (repeatable): spawn[:PORT] (a native "
        "viewer), web[:PORT] (serve the web viewer, default port 9090; the run then keeps serving "
        "until Ctrl-C), connect[:URL] (a running viewer or `rerun --serve-web`, default "
        "rerun+http://127.0.0.1:9876/proxy); default: $HIL_TRACE. trace.rrd is always written",
    )
    trace.add_argument(
        "--keep-serving",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="with a web viewer: keep serving the run's trace after the summary, until Ctrl-C "
        "(the data lives in this process; default: yes)",
    )
    trace.add_argument(
        "--poll-every",
        type=int,
        default=DEFAULT_POLL_EVERY,
        metavar="N",
        help="read the fields a dashboard plots but no PDO carries (the spring constant estimate, "
        "thermal limits...) over SDO every N cycles into the trace (default: "
        f"{DEFAULT_POLL_EVERY}; each read is an SDO round trip between two cycles; 0: never)",
    )
    trace.add_argument(
        "--no-trace", action="store_true", help="no trace at all (faster start: no rerun import)"
    )
    parser.add_argument(
        "--board",
        action="store_true",
        help="run in real time against a board, or a free-running firmware, on the bus of -i/-c "
        "instead of starting the firmware on a private bus (the rig sends SYNC every --period-us)",
    )
    add_bus_options(parser)


def run(args: argparse.Namespace) -> int:
    if args.modules is not None:
        return run_robot_command(args)
    if args.seconds is not None:
        raise UsageError("--seconds is the gait's length: it goes with --modules")
    from hilrig.apps.demo import DemoOptions, demo_run, format_summary, run_demo
    from hilrig.session.builder import BoardInterface
    from hilrig.session.faults import FaultPlan

    table = RigTable.load(args.table)
    board = None
    if args.board:
        config = bus_config(args)  # python-can's configuration fills what the options leave out
        board = BoardInterface(
            config.pop("interface"), config.pop("channel", None), config.pop("bitrate", None), config
        )
    run = RunDescription.from_arguments(args, table, demo_run(args.out, board))
    plant = plant_factory(args, table)
    if not table.is_default_board and args.firmware is None and not args.board:
        raise UsageError(
            f"--firmware: the demo joint's firmware does not run {args.table}'s board: pass its own"
        )
    if not table.is_default_board and args.scenario is None:
        raise UsageError(
            "--scenario: the demo's profiles drive the demo joint; another board's table needs a "
            "scenario file defining `def scenario(rig): ...`"
        )
    if args.firmware_platform != LINUX and not table.is_default_board:
        raise UsageError(f"--firmware-platform {args.firmware_platform}: the demo joint's image only")
    executable = args.firmware or default_image(args.firmware_platform)
    if not args.board and not executable.is_file():
        hint = "build it with `make baremetal`" if args.firmware_platform != LINUX else FIRMWARE_HINT
        raise UsageError(f"firmware {executable} does not exist: {hint}")
    live = _live_sinks(args)
    if args.poll_every < 0:
        raise UsageError(f"--poll-every: expected a number of cycles >= 0, got {args.poll_every}")
    rig = run.rig
    if plant is not None:  # another plant than the demo joint's: its own parameters
        rig = dataclasses.replace(rig, plant=plant, params=None)
    run = run.replace(
        trace=TraceRun(args.out, trace=not args.no_trace, live=tuple(live)),
        firmware=dataclasses.replace(
            run.firmware,
            executable=executable,
            image=executable if args.firmware_platform == QEMU_VIRT else run.firmware.image,
            platform=args.firmware_platform,
            node_id=args.node_id,
        ),
        rig=dataclasses.replace(rig, eds=eds_path(args)),
        bus=dataclasses.replace(run.bus, bitrate=None if args.board else args.bitrate),
    )
    options = DemoOptions(
        run,
        scenario_file=args.scenario,
        faults=FaultPlan(tuple(args.fault)),
        poll_every=args.poll_every,
        table=table,
    )
    summary = run_demo(options, progress=progress)
    return _report(args, format_summary(summary), summary.viewer_url, live)


def plant_factory(args: argparse.Namespace, table: RigTable) -> PlantFactory | None:
    """--plant/--plant-map: the FMU's plant factory, its map checked against `table` and the FMU
    now (a bad map is a usage error); None: the demo joint's own physics."""
    if args.plant is None and args.plant_map is None:
        if not table.is_default_board:
            raise UsageError(
                f"{args.table} is not the demo joint's table: give its plant with --plant "
                "MODEL.fmu --plant-map MAP.toml"
            )
        return None
    if args.plant_map is None:
        raise UsageError("--plant: give the FMU's map too (--plant-map MAP.toml; docs/fmu.md)")
    try:
        from hilrig.plants.fmu import fmu_factory
    except ImportError as error:
        raise UsageError(f"--plant needs FMPy ({error.name} is missing): pip install 'hilrig[fmu]'") from None
    from hilrig.errors import PlantMapError

    try:
        return fmu_factory(args.plant_map, table.board, args.plant)
    except PlantMapError as error:
        raise UsageError(str(error)) from None


def _live_sinks(args: argparse.Namespace) -> list[TraceSink]:
    """--viewer, else $HIL_TRACE; none with --no-trace (and both given: a usage error)."""
    from hilrig.observe.sinks import live_sinks_from_environment

    try:
        live = list(args.viewer) if args.viewer is not None else live_sinks_from_environment()
    except ValueError as error:
        raise UsageError(str(error)) from None
    if args.no_trace and args.viewer:
        raise UsageError("--viewer streams the trace, --no-trace makes none: choose one")
    return [] if args.no_trace else live


def _report(args: argparse.Namespace, text: str, viewer_url: str | None, live: Sequence[TraceSink]) -> int:
    """The summary on stdout and in summary.txt; then, with a web viewer, keep serving."""
    from hilrig.observe.sinks import SinkKind

    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "summary.txt").write_text(text + "\n")
    print(text, flush=True)
    if args.keep_serving and viewer_url is not None and any(s.kind is SinkKind.WEB for s in live):
        # The web viewer's data lives in this process: keep it until the person is done.
        progress(f"sim: the web viewer keeps serving this run at {viewer_url}; Ctrl-C to stop")
        try:
            while True:
                signal.pause()
        except KeyboardInterrupt:
            progress("sim: stopped serving")
    return 0


def run_robot_command(args: argparse.Namespace) -> int:
    """`hilrig sim --modules N`: the robot demo (hilrig.apps.robot_demo)."""
    from hilrig.apps.robot_demo import GAIT_SECONDS, RobotOptions, format_robot_summary, robot_run, run_robot
    from hilrig.session.firmware import DEFAULT_EXECUTABLE

    given = {
        "--board": args.board,
        "--fault": bool(args.fault),
        "--node-id": args.node_id is not None,
        "--plant": args.plant is not None or args.plant_map is not None,
        "--firmware-platform": args.firmware_platform != LINUX,
    }
    refused = [flag for flag, present in given.items() if present]
    if refused:
        raise UsageError(
            f"{', '.join(refused)}: not with --modules (a robot runs its own firmware modules in "
            "lockstep; give their node ids to --modules)"
        )
    seconds = args.seconds if args.seconds is not None else GAIT_SECONDS
    if not (seconds >= 0 and seconds < float("inf")):
        raise UsageError(f"--seconds: expected a finite duration >= 0, got {args.seconds}")
    run = RunDescription.from_arguments(args, RigTable.load(), robot_run(args.out, args.modules))
    executable = args.firmware or DEFAULT_EXECUTABLE
    if not executable.is_file():
        raise UsageError(f"firmware {executable} does not exist: {FIRMWARE_HINT}")
    live = _live_sinks(args)
    run = run.replace(
        trace=TraceRun(args.out, trace=not args.no_trace, live=tuple(live)),
        firmware=dataclasses.replace(run.firmware, executable=executable),
        rig=dataclasses.replace(run.rig, eds=eds_path(args)),
    )
    options = RobotOptions(run, seconds=seconds, scenario_file=args.scenario)
    summary = run_robot(options, progress=progress)
    return _report(args, format_robot_summary(summary), summary.viewer_url, live)


COMMANDS = (
    Command(
        name="sim",
        help="run the demo joint: firmware + physics in lockstep, a summary, the bus log",
        description="Start a private bus (a network namespace with its own vcan0), the firmware in\n"
        "lockstep mode on it and the rig's joint physics; run a velocity then a torque\n"
        "profile (or --scenario FILE.py defining `def scenario(rig): ...`); print the\n"
        "tracking errors, the spring constant estimate, the peak temperature and the\n"
        "faults; leave bus.log (candump), firmware.log and summary.txt in --out.\n\n"
        "Needs root and a kernel with vcan: natively (`sudo .venv/bin/hilrig sim`),\n"
        "or through the micro-VM: `tools/with-vcan -- .venv/bin/hilrig sim`.\n"
        "`make run` runs this.\n\n"
        "Faults (--fault, repeatable) happen at their simulation times: sensor frames\n"
        "dropped or late, sensor values frozen, offset or out of range, malformed frames,\n"
        "a flood, the firmware killed or restarted. A killed firmware ends the run with\n"
        "the cycle it was noticed in and the paths of the trace and logs (exit code 1).\n\n"
        "Live: --viewer spawn | web[:PORT] | connect[:URL] streams the trace while the run\n"
        "goes, beside trace.rrd (`make run VIEWER=web`). A board: --board -i pcan -c\n"
        "PCAN_USBBUS1 runs the same profiles in real time against the board (or a\n"
        "free-running firmware) on that bus.\n\n"
        "  tools/with-vcan -- .venv/bin/hilrig sim --out out/demo\n"
        "  ... sim --fault delay:motor_encoder_counts=20@0.3+0.4 --fault restart@1.5\n"
        "  sudo .venv/bin/hilrig sim --scenario my_scenario.py   # def scenario(rig): ...\n"
        "  hilrig sim --viewer web          # then open http://localhost:9090\n"
        "  hilrig sim --board -c vcan0 --period-us 10000 --viewer connect\n\n"
        "An FMU as the plant: --plant model.fmu --plant-map model.map.toml (docs/fmu.md);\n"
        "the joint's own FMU, which `make build` exports, with its map:\n\n"
        "  ... sim --plant build/fmu/joint.fmu --plant-map build/fmu/joint.map.toml\n"
        "  ... sim --table head.toml --firmware build/bin/head-firmware --plant osc.fmu \\\n"
        "        --plant-map head_osc.map.toml --scenario nod.py\n\n"
        "A robot: --modules 8 starts the firmware 8 times on one bus (node ids 1..8),\n"
        "one SYNC for all, the chain's mechanics from MuJoCo (pip install 'hilrig[robot]'),\n"
        "the rig as master with its heartbeat, and runs a travelling-wave gait (`make run\n"
        "ROBOT=8`): per-joint tracking in the summary, the chain in 3D in the trace.\n\n"
        "  tools/with-vcan -- .venv/bin/hilrig sim --modules 8 --out out/robot",
        configure=configure,
        run=run,
    ),
)
