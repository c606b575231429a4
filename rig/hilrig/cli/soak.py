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
            "Runs SOAK cycles (default a million) against the firmware on a private vcan bus (or "
            "--channel), with a seeded fault now and then; every TPDO of every cycle is checked, the "
            "firmware's stop line against the driver's tally, its RSS and fds sampled. Progress every "
            "10 s, the report (OUT/report.json) every minute and at the end; Ctrl-C stops after the "
            "cycle at hand and still writes it. Exit 0 passed, 1 failed, 130 interrupted. Needs root "
            "and vcan: `make soak`, or `tools/with-vcan -- .venv/bin/hilrig soak`."
        ),
        configure=_configure,
        run=_run,
    ),
)
