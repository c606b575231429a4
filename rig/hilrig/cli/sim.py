"""`hilrig sim`: the demo joint against the real firmware, in lockstep, with a summary."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from hilrig.cli.common import (
    EDS_HINT,
    Command,
    UsageError,
    eds_path,
    existing_file,
    node_id,
    positive_int,
    progress,
)
from hilrig.table import BOARD_TABLE

if TYPE_CHECKING:
    from hilrig.faults import FaultSpec


def fault_spec(text: str) -> FaultSpec:
    from hilrig.faults import FaultSpec, FaultSpecError

    try:
        return FaultSpec.parse(text)
    except FaultSpecError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def configure(parser: argparse.ArgumentParser) -> None:
    from hilrig.faults import FAULT_SYNTAX_HELP  # the fault models need numpy: only for `sim`

    parser.add_argument(
        "--out",
        type=Path,
        default=Path("out/demo"),
        metavar="DIR",
        help="where bus.log, firmware.log and summary.txt go (default: out/demo)",
    )
    parser.add_argument(
        "--scenario",
        type=existing_file("scenario", "pass a .py file that defines `def scenario(rig): ...`"),
        metavar="FILE.py",
        help="run `scenario(rig)` from this file instead of the velocity and torque profiles",
    )
    default_node = BOARD_TABLE.node.default_node_id
    parser.add_argument(
        "-n",
        "--node-id",
        type=node_id,
        default=default_node,
        help=f"node id (default: 0x{default_node:02X}, board.toml's)",
    )
    parser.add_argument(
        "--period-us",
        type=positive_int,
        default=1000,
        metavar="US",
        help="control period, the firmware's --period-us (default: 1000)",
    )
    parser.add_argument("--seed", type=int, default=1, help="sensor noise seed (default: 1)")
    parser.add_argument(
        "--firmware",
        type=existing_file("firmware", "build it with `make build`"),
        default=None,
        help="the joint-firmware executable (default: build/bin/joint-firmware)",
    )
    parser.add_argument(
        "--fault",
        action="append",
        type=fault_spec,
        default=[],
        metavar="SPEC",
        help="inject a fault (repeatable): " + FAULT_SYNTAX_HELP + "; e.g. drop:thermistor_adc@0.5+0.2",
    )
    parser.add_argument(
        "--eds",
        type=existing_file("EDS", EDS_HINT),
        default=None,
        help="the board's EDS (default: build/protocol/board.eds)",
    )


def run(args: argparse.Namespace) -> int:
    from hilrig.demo import DemoOptions, format_summary, run_demo
    from hilrig.faults import FaultPlan
    from hilrig.firmware import DEFAULT_EXECUTABLE

    executable = args.firmware or DEFAULT_EXECUTABLE
    if not executable.is_file():
        raise UsageError(f"firmware {executable} does not exist: build it with `make build`")
    options = DemoOptions(
        out_dir=args.out,
        scenario_file=args.scenario,
        node_id=args.node_id,
        period_us=args.period_us,
        seed=args.seed,
        executable=executable,
        eds=eds_path(args),
        faults=FaultPlan(tuple(args.fault)),
    )
    summary = run_demo(options, progress=progress)
    text = format_summary(summary)
    (args.out / "summary.txt").write_text(text + "\n")
    print(text)
    return 0


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
        "  tools/with-vcan -- .venv/bin/hilrig sim --out out/demo\n"
        "  ... sim --fault delay:motor_encoder_counts=20@0.3+0.4 --fault restart@1.5\n"
        "  sudo .venv/bin/hilrig sim --scenario my_scenario.py   # def scenario(rig): ...",
        configure=configure,
        run=run,
    ),
)
