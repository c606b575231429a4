"""`hilrig bus-load`: will this PDO mapping fit a real CAN bus at this cycle rate?"""

from __future__ import annotations

import argparse
import math
import sys

from hilrig.busload import (
    DEFAULT_RATE_HZ,
    FULL_LOAD,
    STANDARD_BITRATES,
    WARNING_LOAD,
    BusRates,
    lockstep_traffic,
    report,
)
from hilrig.cli.common import Command, UsageError, add_table_option, bitrate, node_id
from hilrig.table import RigTable


def _rate(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a cycle rate in Hz like 1000, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive cycle rate in Hz, got {text!r}")
    return value


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--rate-hz", type=_rate, default=DEFAULT_RATE_HZ, help="control-cycle (SYNC) rate (default 1000)"
    )
    parser.add_argument(
        "-b",
        "--bitrate",
        type=bitrate,
        action="append",
        help="(nominal) bus bit rate, e.g. 500k, 1M or 125000; repeat for several "
        "(default: 125k 250k 500k 1M)",
    )
    parser.add_argument(
        "--fd", action="store_true", help="count the frames as CAN FD frames (implied by --data-bitrate)"
    )
    parser.add_argument(
        "--data-bitrate",
        type=bitrate,
        default=None,
        metavar="BITRATE",
        help="CAN FD data phase bit rate (bit rate switch), e.g. 2M; without it an FD frame is "
        "sent at --bitrate throughout",
    )
    add_table_option(parser)
    parser.add_argument(
        "-n",
        "--node-id",
        type=node_id,
        default=None,
        help="node id for the COB-IDs shown (default: the table's)",
    )


def run(args: argparse.Namespace) -> int:
    """0 it fits (a WARNING line above 70 % is still 0), 1 above 100 % on a bit rate asked for."""
    bitrates = args.bitrate or list(STANDARD_BITRATES)
    if args.data_bitrate is not None and any(rate > args.data_bitrate for rate in bitrates):
        raise UsageError(
            f"--data-bitrate {args.data_bitrate} is below a --bitrate ({max(bitrates)}): the data "
            "phase is the fast one; give --bitrate for the nominal rate(s) you mean"
        )
    table = RigTable.load(args.table).board  # a bad table: TableError, exit code 2
    buses = [BusRates(rate, args.data_bitrate, args.fd) for rate in bitrates]
    traffic = lockstep_traffic(table, args.rate_hz, args.node_id)
    kind = " as CAN FD frames" if buses[0].is_fd else ""
    print(f"bus load of the lockstep exchange{kind}, table {args.table}")
    loads = report(traffic, args.rate_hz, buses, sys.stdout)
    overloaded = [load.rates.label for load in loads if load.overloaded]
    if overloaded:
        sys.stdout.flush()  # the report first, then the verdict
        print(
            f"{args.parser.prog}: error: at {args.rate_hz:g} Hz the exchange does not fit "
            f"{', '.join(overloaded)} (above {100 * FULL_LOAD:.0f} % of the bus)",
            file=sys.stderr,
        )
        return 1
    return 0


COMMANDS = (
    Command(
        name="bus-load",
        help="share of a real CAN (FD) bus the lockstep exchange takes (no bus needed)",
        description="Count the frames of one lockstep cycle (RPDOs, SYNC, TPDOs by transmission type,\n"
        "heartbeat) from the table's PDO layout and the share of a real bus they take, nominal\n"
        "and with worst-case bit stuffing, as classic CAN or as CAN FD frames (arbitration at\n"
        "--bitrate, the data phase at --data-bitrate). Formulas: `pydoc hilrig.busload`.\n"
        f"Above {100 * WARNING_LOAD:.0f} % a WARNING line (exit code 0); above "
        f"{100 * FULL_LOAD:.0f} % on average or in the\nbusiest cycle it does not fit: an OVERLOAD "
        "line and exit code 1.\n\n"
        "  hilrig bus-load                                # the default mapping, 1 kHz, all bit rates\n"
        "  hilrig bus-load --rate-hz 200 --bitrate 500k   # will it fit a 500 kbit/s bus at 200 Hz?\n"
        "  hilrig bus-load -b 500k --data-bitrate 2M      # the same frames as CAN FD, 2 Mbit/s data\n"
        "  hilrig bus-load --table my_board.toml          # another board's table",
        configure=configure,
        run=run,
    ),
)
