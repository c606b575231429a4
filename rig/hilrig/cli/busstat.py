"""`hilrig busstat`: what a bus really carries, measured on a live bus or from a log file."""

from __future__ import annotations

import argparse
import sys

from hilrig.cli.common import (
    Command,
    UsageError,
    add_bus_options,
    add_table_option,
    describe_bus,
    load_table,
    node_id,
    open_bus,
    positive_float,
    progress,
)
from hilrig.cli.record import existing_log

DEFAULT_DURATION_S = 5.0


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "file",
        type=existing_log,
        nargs="?",
        metavar="FILE",
        help="a log file (the formats `replay` reads); without it, the live bus of the bus options",
    )
    parser.add_argument(
        "--rate-hz",
        type=positive_float,
        default=None,
        help="the SYNC rate: time is counted in SYNC cycles of 1/RATE s (a lockstep log, as "
        "`bus-load --rate-hz` counts); without it, the frames' timestamps",
    )
    parser.add_argument(
        "--duration",
        type=positive_float,
        default=DEFAULT_DURATION_S,
        metavar="S",
        help=f"live bus: seconds to listen (default {DEFAULT_DURATION_S:g}; Ctrl-C ends early)",
    )
    parser.add_argument(
        "-n",
        "--node-id",
        type=node_id,
        default=None,
        help="the node whose PDOs are named and whose TPDO delays are measured (default: the table's)",
    )
    add_table_option(parser)
    add_bus_options(parser)


def run(args: argparse.Namespace) -> int:
    """0 with the report; a usage error without a bit rate."""
    from hilrig.apps.busload import DEFAULT_RATE_HZ, lockstep_traffic
    from hilrig.apps.busstat import measure, report
    from hilrig.session.buslog import read_log
    from hilrig.session.canbus import received

    no_bitrate = UsageError("give the bus's bit rate with -b (e.g. -b 1M): the load is a share of it")
    if args.bitrate is None and args.file is None:
        raise no_bitrate
    table = load_table(args)
    node = args.node_id if args.node_id is not None else table.board.node.default_node_id
    names = {t.can_id: t.name for t in lockstep_traffic(table.board, args.rate_hz or DEFAULT_RATE_HZ, node)}
    tpdos = [pdo.cob_id(node) for pdo in table.board.tpdos if pdo.enabled]
    if args.file is not None:
        with read_log(args.file) as logged:  # a format it does not read is said first
            if args.bitrate is None:
                raise no_bitrate
            stats = measure(logged, tpdos, args.rate_hz)
        where = str(args.file)
    else:
        with open_bus(args) as bus:
            progress(f"busstat: listening on {describe_bus(args)} for {args.duration:g} s")
            stats = measure(received(bus, args.duration), tpdos, args.rate_hz)
        where = describe_bus(args)
    if args.rate_hz is not None and stats.cycles == 0:
        raise UsageError(f"{where}: fewer than 2 SYNCs, no cycle to count at --rate-hz {args.rate_hz:g}")
    print(f"bus statistics of {where}" + (f", at {args.rate_hz:g} Hz per SYNC" if args.rate_hz else ""))
    report(stats, args.bitrate, names, sys.stdout, per_cycle=args.rate_hz is not None)
    return 0


COMMANDS = (
    Command(
        name="busstat",
        help="measured bus load, frames per COB-ID, error frames, TPDO delay after SYNC (live or a log)",
        description=(__doc__ or "").strip() + "\n\n"
        "Each frame counts with its nominal and worst-case bits (`pydoc hilrig.apps.busload`), as a\n"
        "share of -b; per COB-ID its frames per second; the TPDOs' delay after their SYNC as min,\n"
        "median and max. `pydoc hilrig.apps.busstat` says how time is counted.\n\n"
        "  hilrig busstat out/demo/bus.log -b 1M --rate-hz 1000   # a lockstep log, per SYNC\n"
        "  hilrig busstat -c can0 -b 500k --duration 10           # a live bus for 10 s\n"
        "  hilrig bus-load -b 1M --rate-hz 1000                   # what the table says, beside it",
        configure=configure,
        run=run,
    ),
)
