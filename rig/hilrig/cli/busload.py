"""`hilrig bus-load`: will this PDO mapping fit a real CAN bus at this cycle rate?"""

from __future__ import annotations

import argparse
import math
import sys

from boardproto import UnknownNameError
from boardproto.cia301 import MAX_NODE_ID_WITH_PDO_5_TO_8, heartbeat_cob_id
from hilrig.apps.busload import (
    DEFAULT_MASTER_HEARTBEAT_MS,
    DEFAULT_MASTER_NODE_ID,
    DEFAULT_RATE_HZ,
    FULL_LOAD,
    STANDARD_BITRATES,
    WARNING_LOAD,
    BusRates,
    highest_rate_hz,
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


# PDO 5..8 of node N take the COB-IDs of PDO 1..4 of node N + 64 (board.toml's default layout):
# node ids 1..63 keep every module's identifiers apart.
MAX_MODULES = MAX_NODE_ID_WITH_PDO_5_TO_8
MAX_HEARTBEAT_MS = 0xFFFF  # CiA 301 heartbeat times are UNSIGNED16 milliseconds


def _module_count(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if not 1 <= value <= MAX_MODULES:
        raise argparse.ArgumentTypeError(
            f"expected a number of modules 1..{MAX_MODULES} (node ids 1..N), got {text!r}"
        )
    return value


def _heartbeat_ms(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = -1
    if not 0 <= value <= MAX_HEARTBEAT_MS:
        raise argparse.ArgumentTypeError(
            f"expected a heartbeat period 0..{MAX_HEARTBEAT_MS} in ms (0: none), got {text!r}"
        )
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
        "--profile",
        default=None,
        metavar="NAME",
        help="a PDO profile of the table ([[pdo_profile]]: full, lean...) instead of its default mapping",
    )
    parser.add_argument(
        "-n",
        "--node-id",
        type=node_id,
        default=None,
        help="node id for the COB-IDs shown (default: the table's)",
    )
    robot = parser.add_argument_group("a robot: identical modules on one bus")
    robot.add_argument(
        "--modules",
        type=_module_count,
        default=None,
        metavar="N",
        help=f"N modules with the table's PDOs, node ids 1..N (1..{MAX_MODULES}), one SYNC per cycle "
        "for all and the master's heartbeat",
    )
    robot.add_argument(
        "--master-heartbeat-ms",
        type=_heartbeat_ms,
        default=None,
        metavar="MS",
        help=f"the master's heartbeat period (1 byte on 0x{heartbeat_cob_id(DEFAULT_MASTER_NODE_ID):03X}), "
        f"with --modules; 0: none (default {DEFAULT_MASTER_HEARTBEAT_MS})",
    )


def run(args: argparse.Namespace) -> int:
    """0 it fits (a WARNING line above 70 % is still 0), 1 above 100 % on a bit rate asked for
    (-b); without -b the survey of the standard bit rates only reports, exit code 0."""
    bitrates = args.bitrate or list(STANDARD_BITRATES)
    if args.data_bitrate is not None and any(rate > args.data_bitrate for rate in bitrates):
        raise UsageError(
            f"--data-bitrate {args.data_bitrate} is below a --bitrate ({max(bitrates)}): the data "
            "phase is the fast one; give --bitrate for the nominal rate(s) you mean"
        )
    if args.modules is None and args.master_heartbeat_ms is not None:
        raise UsageError("--master-heartbeat-ms is the robot master's: give it with --modules N")
    if args.modules is not None and args.node_id is not None:
        raise UsageError("--node-id names one node: with --modules N the node ids are 1..N")
    table = RigTable.load(args.table).board  # a bad table: TableError, exit code 2
    if args.profile is not None:
        try:
            table = table.with_pdo_profile(args.profile)
        except UnknownNameError as error:
            raise UsageError(f"--profile: {error}") from None
    buses = [BusRates(rate, args.data_bitrate, args.fd) for rate in bitrates]
    node_ids: range | None = None
    master_heartbeat_ms: int | None = None
    heading = "the lockstep exchange"
    if args.modules is not None:
        node_ids = range(1, args.modules + 1)
        master_heartbeat_ms = (
            DEFAULT_MASTER_HEARTBEAT_MS if args.master_heartbeat_ms is None else args.master_heartbeat_ms
        )
        master = (
            f"master heartbeat every {master_heartbeat_ms} ms"
            if master_heartbeat_ms
            else "no master heartbeat"
        )
        modules = (
            f"{args.modules} modules (node ids 1..{args.modules}"
            if args.modules > 1
            else "1 module (node id 1"
        )
        heading = f"a robot of {modules}, one SYNC, {master})"
    try:
        traffic = lockstep_traffic(
            table, args.rate_hz, args.node_id, node_ids=node_ids, master_heartbeat_ms=master_heartbeat_ms
        )
    except ValueError as error:  # COB-IDs that collide: the table's, for this many modules
        raise UsageError(f"{error}; fewer --modules or other COB-ID bases in the table") from None
    kind = " as CAN FD frames" if buses[0].is_fd else ""
    profile = f", PDO profile {args.profile}" if args.profile is not None else ""
    print(f"bus load of {heading}{kind}, table {args.table}{profile}")
    loads = report(traffic, args.rate_hz, buses, sys.stdout)
    highest = [
        highest_rate_hz(
            table, bus, node_id=args.node_id, node_ids=node_ids, master_heartbeat_ms=master_heartbeat_ms
        )
        for bus in buses
    ]
    print(
        f"highest SYNC rate within {100 * WARNING_LOAD:.0f} % (worst case): "
        + ", ".join(
            f"{bus.label}: {f'{rate:.1f} Hz' if rate else 'none (not even 0.1 Hz)'}"
            for bus, rate in zip(buses, highest, strict=True)
        )
    )
    overloaded = [load.rates.label for load in loads if load.overloaded]
    if overloaded and args.bitrate is None:
        # The survey of the standard bit rates asked about no bus: it explains, it does not fail.
        fits = ", ".join(load.rates.label for load in loads if not load.overloaded)
        print(
            f"at {args.rate_hz:g} Hz the exchange fits {fits or 'none of these bit rates'}; "
            "give -b BITRATE for the bus you mean (exit code 1 when it does not fit)"
        )
        return 0
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
        "--bitrate, the data phase at --data-bitrate). Formulas: `pydoc hilrig.apps.busload`.\n"
        f"Above {100 * WARNING_LOAD:.0f} % a WARNING line (exit code 0); above "
        f"{100 * FULL_LOAD:.0f} % on average or in the\nbusiest cycle it does not fit: an OVERLOAD "
        "line and exit code 1 for a bit rate given with -b\n(without -b every standard bit rate is "
        "reported, exit code 0).\n\n"
        "  hilrig bus-load                                # the default mapping, 1 kHz, all bit rates\n"
        "  hilrig bus-load --rate-hz 200 --bitrate 500k   # will it fit a 500 kbit/s bus at 200 Hz?\n"
        "  hilrig bus-load -b 500k --data-bitrate 2M      # the same frames as CAN FD, 2 Mbit/s data\n"
        "  hilrig bus-load --table my_board.toml          # another board's table\n"
        "  hilrig bus-load --profile lean -b 1M           # the table's PDO profile 'lean'\n"
        "  hilrig bus-load --modules 8 -b 1M              # a robot: 8 modules (node ids 1..8) on one bus\n\n"
        "--modules N: N identical modules with the table's PDOs (COB-IDs base + node id), one SYNC\n"
        "per cycle for all and the master's heartbeat (--master-heartbeat-ms, default "
        f"{DEFAULT_MASTER_HEARTBEAT_MS}). The last line\ngives the highest SYNC rate "
        f"within {100 * WARNING_LOAD:.0f} % per bit rate (worst case, average and busiest cycle).",
        configure=configure,
        run=run,
    ),
)
