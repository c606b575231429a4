"""`hilrig soak`: a million lockstep cycles against the real firmware with seeded faults."""

from __future__ import annotations

import argparse
from pathlib import Path

from hilrig.cli.common import (
    Command,
    UsageError,
    positive_int,
)
from hilrig.cli.files import output_file, output_folder


def _configure(parser: argparse.ArgumentParser) -> None:
    """The soak's options (`hilrig soak --help`)."""
    from hilrig.apps.soak.fault_plan import DEFAULT_FAULT_INTERVAL
    from hilrig.apps.soak.memory import DEFAULT_RSS_BOUND_KIB, DEFAULT_SAMPLE_EVERY
    from hilrig.session.run import RunDescription

    parser.add_argument(
        "--cycles", type=positive_int, default=1_000_000, help="firmware cycles to run (default 1000000)"
    )
    parser.add_argument(
        "--out", type=output_folder, default=Path("build/soak"), help="report.json and firmware.log go here"
    )
    parser.add_argument("--seed", type=int, default=11, help="seed of the fault plan (default 11)")
    parser.add_argument(
        "--fault-interval", type=positive_int, default=DEFAULT_FAULT_INTERVAL, help="cycles between faults"
    )
    parser.add_argument(
        "--sample-every", type=positive_int, default=DEFAULT_SAMPLE_EVERY, help="cycles between RSS samples"
    )
    parser.add_argument(
        "--rss-bound-kib", type=int, default=DEFAULT_RSS_BOUND_KIB, help="allowed growth after warm-up"
    )
    RunDescription.add_arguments(parser, "node_id", "period_us", "firmware", "eds")
    parser.add_argument("--channel", help="use this interface as it is (default: a private namespace vcan0)")
    parser.add_argument(
        "--stop-file", type=output_file("stop file"), help="stop cleanly once this file exists (tools/soak)"
    )
    parser.add_argument(
        "--pin", action="store_true", help="pin soak and firmware to one CPU (slower with canopen's thread)"
    )
    parser.add_argument("--cpu", type=int, help="the CPU to pin to (default: the last one allowed)")
    parser.add_argument(
        "--keep-thp",
        action="store_true",
        help="leave transparent huge pages on for the firmware (khugepaged then makes its RSS jump)",
    )


def _run(args: argparse.Namespace) -> int:
    from hilrig.apps.soak.run import run

    def usage_error(message: str) -> int:
        raise UsageError(message)

    return run(args, usage_error)


COMMANDS = (
    Command(
        name="soak",
        help="lockstep cycles against the real firmware with seeded faults: no cycle lost, memory flat",
        description=(
            "Runs --cycles lockstep cycles (default a million) against the firmware on a private\n"
            "vcan bus (or --channel), with a seeded fault now and then: every TPDO of every cycle is\n"
            "checked, the firmware's stop line against the soak's tally, its RSS and fds sampled.\n"
            "Progress every 10 s; the report (OUT/report.json) every minute and at the end. Ctrl-C\n"
            "stops after the cycle at hand and still writes it. Exit 0 passed, 1 failed, 130\n"
            "interrupted. Needs root and vcan:\n\n"
            "  make soak SOAK_CYCLES=1000000                            # through the micro-VM\n"
            "  tools/with-vcan -- .venv/bin/hilrig soak --cycles 20000 --fault-interval 2000\n"
        ),
        configure=_configure,
        run=_run,
    ),
)
