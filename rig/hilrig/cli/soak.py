"""`hilrig soak`: a million lockstep cycles against the real firmware with seeded faults."""

from __future__ import annotations

import argparse

from hilrig.cli.common import Command, UsageError


def _configure(parser: argparse.ArgumentParser) -> None:
    from hilrig.soak import add_arguments

    add_arguments(parser)


def _run(args: argparse.Namespace) -> int:
    from hilrig.soak import run

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
            "checked, the firmware's stop line against the driver's tally, its RSS and fds sampled.\n"
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
