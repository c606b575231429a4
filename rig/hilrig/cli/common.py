"""What every `hilrig` command shares: the command registry entry, the bus and node options,
opening the bus (`hilrig.session.canbus`) with errors as usage errors, and value formatting.

Heavy imports (python-can, canopen, cantools, through the layers below) happen inside the
functions that need them, so `hilrig --help` and `hilrig fields` stay quick (each import costs
seconds in the micro-VM).
"""

from __future__ import annotations

import argparse
import contextlib
import difflib
import os
import re
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

from boardproto.cia402 import STATUSWORD_INDEX, STATUSWORD_STATES, StatuswordStates
from boardproto.table import BitSet, ValueEnum
from hilrig import resources
from hilrig.arguments import node_id as node_id  # the commands import it from here
from hilrig.arguments import positive_float
from hilrig.arguments import positive_int as positive_int  # the commands import it from here
from hilrig.cli.files import ArgKind, existing_file, kind, sniff_eds, sniff_toml
from hilrig.errors import (
    ConfigurationError,
    FieldNameError,
    IdentityMismatchError,
    RigError,
    SdoAbortError,
    one_line,
)
from hilrig.resources import DBC_HINT, EDS_HINT
from hilrig.session import canbus
from hilrig.session.canbus import BusOptionError
from hilrig.session.canbus import CanFilter as CanFilter  # the commands and their tests import it from here
from hilrig.table import ObjectEntry, RigTable
from hilrig.wire.bustime import IDEAL

if TYPE_CHECKING:
    import cantools.database

    from hilrig.observe.sinks import TraceSink
    from hilrig.session.canbus import Bus
    from hilrig.wire.node import BoardNode, ObjectDictionary


class UsageError(RigError, ValueError):
    """The command line is wrong (exit code 2); the message says what to type instead."""


@dataclass(frozen=True)
class Command:
    """One subcommand: `configure` adds its arguments, `run` does the work and returns the
    exit code. Register it by listing it in the `COMMANDS` tuple of a module named in
    `hilrig.cli.COMMAND_MODULES`."""

    name: str
    help: str
    description: str
    configure: Callable[[argparse.ArgumentParser], None]
    run: Callable[[argparse.Namespace], int]


# --- Argument types (argparse turns ValueError/ArgumentTypeError into exit code 2) ---------
@kind(ArgKind("name", out_of_range="socketcn"))
def interface_name(text: str) -> str:
    """A python-can interface name; unknown ones are refused with the close matches."""
    valid = canbus.interface_names()
    if text in valid:
        return text
    matches = difflib.get_close_matches(text, sorted(valid), n=3, cutoff=0.5)
    hint = f"did you mean {' or '.join(matches)}? " if matches else ""
    raise argparse.ArgumentTypeError(
        f"unknown python-can interface {text!r}; {hint}known: {', '.join(sorted(valid))}"
    )


@kind(ArgKind("name", out_of_range="no_such_field"))
def field_name(text: str) -> str:
    """A field name; checked against the table when the command runs (`check_names`: --table
    may name another table)."""
    return text


@kind(ArgKind("name", out_of_range="no_such_field=1"))
def assignment(text: str) -> str:
    """NAME=VALUE; checked against the table when the command runs."""
    return text


MAX_PORT = 65535


@kind(ArgKind("port", out_of_range=str(MAX_PORT + 1)))
def port(text: str) -> int:
    """A TCP port, 1..65535."""
    try:
        value = int(text, 0)
    except ValueError:
        value = 0
    if not 1 <= value <= MAX_PORT:
        raise argparse.ArgumentTypeError(f"expected a TCP port 1..{MAX_PORT}, got {text!r}")
    return value


def required_file(path: Path, what: str, hint: str) -> Path:
    """`path` if it is a file; else the usage error `existing_file` gives for a typed one (for
    defaults, which argparse does not check: build/protocol/board.eds before `make build`)."""
    if not path.is_file():
        raise UsageError(f"{what} {path} does not exist; {hint}")
    return path


_BITRATE = re.compile(r"(?P<number>\d+(?:\.\d+)?)\s*(?P<scale>[kKmM]?)")
_BITRATE_SCALE = {"": 1, "k": 1_000, "m": 1_000_000}


@kind(ArgKind("number", out_of_range="0"))
def bitrate(text: str) -> int:
    """'125000', '500k', '1M', '2.5M' -> bit/s: every bit rate option and python-can's
    configured bit rates go through this one parser."""
    match = _BITRATE.fullmatch(text.strip())
    value = float(match["number"]) * _BITRATE_SCALE[match["scale"].lower()] if match else 0.0
    if not value >= 1 or value != int(value):
        raise argparse.ArgumentTypeError(
            f"expected a bit rate in bit/s like 125000, 500k or 1M, got {text!r}"
        )
    return int(value)


@kind(ArgKind("number", out_of_range="0"))
def bus_timing(text: str) -> int | None:
    """A timed bus option: a bit rate as `bitrate` reads it, or 'ideal' -> None (no bit rate:
    the virtual bus carries every frame in its cycle; `hilrig.wire.bustime`)."""
    return None if text.strip().lower() == IDEAL else bitrate(text)


_BUS_KWARG = re.compile(r"(?P<name>[_a-zA-Z][-_a-zA-Z0-9]*)=(?P<value>\S*)")


def bus_kwarg(text: str) -> tuple[str, Any]:
    """'app_name=MyApp' -> ('app_name', 'MyApp'), the value typed as python-can's `can.logger
    --bus-kwargs` types it ('1' -> 1, '0.5' -> 0.5, 'True' -> True)."""
    match = _BUS_KWARG.fullmatch(text)
    if match is None:
        raise argparse.ArgumentTypeError(
            f"expected KEY=VALUE for the interface (e.g. serial=1234), got {text!r}"
        )
    return match["name"].replace("-", "_"), canbus.option_value(match["value"])


MAX_CAN_ID = 0x1FFF_FFFF  # 29-bit identifiers


def can_filter(text: str) -> CanFilter:
    """'180:780' (hex, as python-can's and candump's filters) -> CanFilter; '~' inverts."""
    separator = ":" if ":" in text else "~"
    id_text, found, mask_text = text.partition(separator)
    try:
        can_id, can_mask = int(id_text, 16), int(mask_text, 16)
    except ValueError:
        found = ""
    if not found or not (0 <= can_id <= MAX_CAN_ID and 0 <= can_mask <= MAX_CAN_ID):
        raise argparse.ArgumentTypeError(
            f"expected a filter CAN_ID:MASK (keep) or CAN_ID~MASK (drop), in hex as python-can's "
            f"logger takes them, e.g. 180:780, got {text!r}"
        )
    return CanFilter(can_id, can_mask, inverted=separator == "~")


# --- Option groups ---------------------------------------------------------------------
@kind(ArgKind("viewer", out_of_range="web:99999"))
def live_sink(text: str) -> TraceSink:
    """A `--viewer` value: spawn[:PORT] | web[:PORT[:GRPC_PORT]] | connect[:URL]; spawn on a
    machine without a display is refused (the viewer would die with a windowing error)."""
    from hilrig.observe.sinks import SinkKind, parse_live_sink

    try:
        sink = parse_live_sink(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None
    if sink.kind is SinkKind.SPAWN and not has_display():
        raise argparse.ArgumentTypeError(
            f"{text!r}: {NO_DISPLAY}; use web[:PORT] and open the page it prints"
        )
    return sink


NO_DISPLAY = "no display here for a native viewer (neither DISPLAY nor WAYLAND_DISPLAY is set)"


def has_display() -> bool:
    """Whether a native window can open: on Linux an X or Wayland display must be named."""
    if not sys.platform.startswith("linux"):
        return True
    return any(os.environ.get(name) for name in ("DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET"))


LIVE_VIEWER_HELP = (
    "spawn[:PORT] (a native viewer), web[:PORT] (serve the web viewer, default port 9090), "
    "connect[:URL] (a running viewer or `rerun --serve-web`, default rerun+http://127.0.0.1:9876/proxy)"
)


TABLE_HELP = (
    f"the board field table; not given: {resources.TABLE_ORDER}; the EDS and DBC of another table "
    "are generated for it"
)


def add_table_option(parser: argparse.ArgumentParser) -> None:
    """--table; not given, `choose_table` picks the project's (resources.TABLE_ORDER)."""
    parser.add_argument(
        "--table",
        type=existing_file(
            "board table", "pass --table PATH/board.toml", suffixes=(".toml",), sniff=sniff_toml
        ),
        default=None,
        metavar="TOML",
        help=TABLE_HELP,
    )


def choose_table(args: argparse.Namespace) -> None:
    """args.table, for a command that has the option: the table of resources.TABLE_ORDER. When
    it came from the project's configuration (not --table, not the default), one line on stderr
    says which and why."""
    if not hasattr(args, "table"):
        return
    try:
        choice = resources.chosen_table(args.table)
    except ConfigurationError as error:
        raise UsageError(str(error)) from None
    given, args.table = args.table, choice.path
    if not choice.is_default and given is None:
        progress(f"hilrig: table {shown_path(choice.path)} ({choice.source})")


def shown_path(path: Path) -> str:
    """A path as a person would type it here: './board.toml' below the working folder, else as is."""
    try:
        return f"./{path.resolve().relative_to(Path.cwd().resolve())}"
    except (ValueError, OSError):
        return str(path)


def add_verbose_option(parser: argparse.ArgumentParser) -> None:
    """-v/--verbose; on a command's own parser too, so it may follow the command's name."""
    parser.add_argument(
        "-v",
        "--verbose",
        action="store_true",
        default=argparse.SUPPRESS,  # a command's parser leaves `hilrig -v COMMAND` as it was
        help="log what python-can and canopen do (to stderr)",
    )


def add_bus_options(parser: argparse.ArgumentParser, *, filters: bool = False) -> None:
    """python-can's bus options, spelt as its own tools spell them (`python -m can.logger`);
    what is not given comes from python-can's configuration, as for `can.Bus()`."""
    group = parser.add_argument_group(
        "bus (any python-can interface)",
        "Not given: from python-can's configuration (~/.canrc or can.ini, the CAN_INTERFACE,\n"
        "CAN_CHANNEL, CAN_BITRATE and CAN_CONFIG environment variables); with none: socketcan vcan0.",
    )
    group.add_argument(
        "-i",
        "--interface",
        type=interface_name,
        default=None,
        help="python-can interface: socketcan, pcan, kvaser, slcan, vector, virtual...",
    )
    group.add_argument(
        "-c",
        "--channel",
        default=None,
        help="channel of that interface: vcan0, can0, PCAN_USBBUS1, /dev/ttyACM0...",
    )
    group.add_argument(
        "-b",
        "--bitrate",
        type=bitrate,
        default=None,
        help="bit rate, e.g. 500k, 1M or 125000, for adapters that set it (pcan, kvaser, slcan); "
        "SocketCAN takes it from `ip link`",
    )
    group.add_argument(
        "--fd", action="store_const", const=True, default=None, help="CAN FD (implied by --data-bitrate)"
    )
    group.add_argument(
        "--data-bitrate",
        type=bitrate,
        default=None,
        metavar="BITRATE",
        help="CAN FD data phase bit rate, e.g. 2M",
    )
    group.add_argument(
        "--bus-kwargs",
        type=bus_kwarg,
        nargs="+",
        default=None,
        metavar="KEY=VALUE",
        help="more keyword arguments of the interface, as python-can's tools take them: "
        "`-i vector -c 1 --bus-kwargs app_name=MyApp serial=1234`",
    )
    if filters:
        group.add_argument(
            "--filter",
            dest="filters",
            type=can_filter,
            nargs="+",
            default=None,
            metavar="ID:MASK",
            help="keep only frames with (id & MASK) == (ID & MASK); ID~MASK keeps those that differ; a "
            "frame one filter keeps is kept; hex, python-can's spelling: --filter 190:7FF 700:780 "
            "(node 0x10's TPDO1 and every heartbeat)",
        )


FORCE_HELP = (
    "write even to a node whose 0x1018 vendor id and product code are not the table's; without it "
    "they are compared before anything is written and a mismatch is refused, exit code 2"
)


def add_node_options(
    parser: argparse.ArgumentParser, *, sdo_timeout_s: float = 1.0, writes: bool = False
) -> None:
    """The bus, the node and the table; a command that `writes` to the node also gets --force
    (`board_node(..., writes=True)` checks the node's identity)."""
    add_bus_options(parser)
    group = parser.add_argument_group("node")
    group.add_argument(
        "-n",
        "--node-id",
        type=node_id,
        default=None,
        help="CANopen node id, 1..127, decimal or 0x hex (default: from the table, 0x10)",
    )
    group.add_argument(
        "--eds",
        type=existing_file("EDS", EDS_HINT, sniff=sniff_eds),
        default=None,
        help="the board's EDS (default: the table's: build/protocol/board.eds in a checkout)",
    )
    group.add_argument(
        "--sdo-timeout",
        type=positive_float,
        default=sdo_timeout_s,
        metavar="S",
        help=f"seconds to wait for each SDO answer (default: {sdo_timeout_s:g})",
    )
    if writes:
        group.add_argument("--force", action="store_true", help=FORCE_HELP)
    add_table_option(parser)


# --- Table and values ------------------------------------------------------------------
def load_table(args: argparse.Namespace) -> RigTable:
    """The table `choose_table` chose (the default one when no command line chose)."""
    return RigTable.load(args.table) if args.table is not None else RigTable.load()


def check_names(table: RigTable, names: list[str]) -> list[ObjectEntry]:
    """The entries of `names`; a name not in the table is a usage error with close matches."""
    try:
        return [table.entry(name) for name in names]
    except FieldNameError as error:
        raise UsageError(f"{error} (`hilrig fields` lists every name)") from None


def resolved_node_id(args: argparse.Namespace, table: RigTable) -> int:
    return args.node_id if args.node_id is not None else table.board.node.default_node_id


Named = ValueEnum | BitSet | StatuswordStates


def value_names(table: RigTable) -> dict[str, Named]:
    """What names the values of each object that has named values: the table's enums and bitsets
    (board.toml's `values`), and a CiA 402 statusword's state (boardproto.cia402)."""
    named: dict[str, Named] = dict(table.board.named_values)
    for entry in table.board.entries:
        if entry.index == STATUSWORD_INDEX and entry.subindex == 0:
            named[entry.name] = STATUSWORD_STATES
    return named


def format_value(value: float | None, named: Named | None = None) -> str:
    """The number; for a field whose values have names in board.toml, the name first:
    'velocity (1)', 'motor_encoder_stale|thermistor_stale (5)', 'none (0)'."""
    if value is None:
        return "-"
    text = f"{value:.6g}" if isinstance(value, float) else str(value)
    return f"{named.label(float(value))} ({text})" if named is not None else text


def format_unit(unit: str) -> str:
    """'' for dimensionless ('1'), else the unit."""
    return "" if unit == "1" else unit


def print_table(
    rows: list[list[str]],
    header: list[str] | None = None,
    *,
    out: TextIO | None = None,
    right: frozenset[int] = frozenset(),
) -> None:
    """Columns padded to their widest cell; columns in `right` are right-aligned."""
    out = out if out is not None else sys.stdout
    all_rows = ([header] if header else []) + rows
    if not all_rows:
        return
    widths = [max(len(row[i]) for row in all_rows) for i in range(len(all_rows[0]))]
    for row in all_rows:
        cells = [
            cell.rjust(w) if i in right else cell.ljust(w)
            for i, (cell, w) in enumerate(zip(row, widths, strict=True))
        ]
        out.write("  ".join(cells).rstrip() + "\n")


def progress(message: str) -> None:
    """A progress line on stderr (stdout stays clean for the results)."""
    print(message, file=sys.stderr, flush=True)


# --- Bus and node ----------------------------------------------------------------------
def describe_bus(args: argparse.Namespace) -> str:
    """'socketcan channel vcan0': the bus `open_bus` opened; before it is open, what the command
    line names, or "python-can's default configuration"."""
    if args.interface is None:
        channel = f" channel {args.channel}" if args.channel is not None else ""
        return f"python-can's default configuration{channel}"
    return f"{args.interface} channel {args.channel}" if args.channel is not None else args.interface


def bus_config(args: argparse.Namespace) -> dict[str, Any]:
    """The keyword arguments of `can.Bus`: the command line first, then python-can's
    configuration (`hilrig.session.canbus.bus_config`), then socketcan on vcan0 when nothing
    names an interface; an unusable configuration is a usage error."""
    given: dict[str, Any] = dict(args.bus_kwargs or ())
    for key in ("interface", "channel", "bitrate", "fd", "data_bitrate"):
        if getattr(args, key, None) is not None:
            given[key] = getattr(args, key)
    # The kernel or adapter filters; an inverted filter is applied by the command instead.
    filters: list[CanFilter] | None = getattr(args, "filters", None)
    try:
        config = canbus.bus_config(given, filters)
    except BusOptionError as error:
        raise UsageError(str(error)) from None
    for key in ("bitrate", "data_bitrate"):
        if isinstance(config.get(key), str):  # CAN_BITRATE=500k: one parser for every bit rate
            try:
                config[key] = bitrate(config[key])
            except argparse.ArgumentTypeError as error:
                raise UsageError(f"python-can's configuration: {key}: {error}") from None
    return config


@contextlib.contextmanager
def open_bus(args: argparse.Namespace, **kwargs: object) -> Iterator[Bus]:
    """The python-can bus of the bus options (`bus_config`) plus the command's own `kwargs`;
    afterwards args.interface and args.channel name the bus opened. An interface that cannot
    work on this machine (not installed, wrong platform, wrong options) is a usage error;
    one that could but does not open (no adapter, no such channel) fails the command."""
    config = {**bus_config(args), **kwargs}
    args.interface = config["interface"]
    args.channel = config.get("channel")
    try:
        bus = canbus.open_bus(config)
    except BusOptionError as error:
        raise UsageError(str(error)) from error
    try:
        yield bus
    finally:
        bus.shutdown()


def eds_path(args: argparse.Namespace) -> Path:
    """--eds, else the EDS of --table (`resources.board_files`); missing: a usage error saying how
    to get one."""
    if args.eds is not None:
        return args.eds
    return required_file(resources.eds_for(getattr(args, "table", None)), "EDS", EDS_HINT)


def dbc_path(args: argparse.Namespace) -> Path:
    """--dbc, else the DBC of --table; `load_dbc` says what to do when it is missing."""
    given = getattr(args, "dbc", None)  # commands without --dbc take the table's
    return given if given is not None else resources.dbc_for(getattr(args, "table", None))


def load_eds(path: Path, node_id: int) -> ObjectDictionary:
    """The object dictionary of an EDS for node `node_id` (its $NODEID+... COB-IDs resolved);
    one canopen cannot read is a usage error (exit 2)."""
    from hilrig.wire.node import node_dictionary

    try:
        return node_dictionary(path, node_id)
    except Exception as error:  # configparser, KeyError, ValueError...: the file, not the rig
        raise UsageError(
            f"EDS {path} is not an EDS canopen can read ({one_line(error)}); {EDS_HINT}"
        ) from None


def load_dbc(path: Path) -> cantools.database.can.Database:
    """A DBC (`dbc_path`); missing or unreadable: a usage error."""
    import cantools

    required_file(path, "DBC", DBC_HINT)
    try:
        database = cantools.database.load_file(str(path))
    except Exception as error:  # cantools' parse errors have no common base
        raise UsageError(
            f"DBC {path} is not a DBC cantools can read ({one_line(error)}); {DBC_HINT}"
        ) from None
    if not isinstance(database, cantools.database.can.Database):
        raise UsageError(f"{path} is no CAN database (a DBC); {DBC_HINT}")
    return database


@contextlib.contextmanager
def board_node(
    args: argparse.Namespace, bus: Bus, table: RigTable, *, writes: bool = False
) -> Iterator[BoardNode]:
    """The node of the node options; one the command `writes` to has passed `check_board`."""
    from hilrig.wire.node import BoardNode

    node_id = resolved_node_id(args, table)
    od = load_eds(eds_path(args), node_id)
    node = BoardNode(bus, node_id, od, table, sdo_timeout_s=args.sdo_timeout)
    try:
        if writes:
            check_board(node, args)
        yield node
    finally:
        node.close()


class WrongBoardError(UsageError):
    """The node is not the table's board (0x1018 differs, or cannot be read): nothing written."""


def check_board(node: BoardNode, args: argparse.Namespace) -> None:
    """Before a command writes to `node`: its 0x1018 vendor id and product code against the
    table's (`BoardNode.check_identity`). A mismatch, or an identity the node will not tell, is
    WrongBoardError (exit code 2) before anything is written; with --force a warning line, and
    the command goes on. A node that does not answer fails as any SDO timeout does."""
    from hilrig.wire.node import identity_text

    table = shown_path(Path(node.table.board.source))
    expected = identity_text(node.table.board.node.vendor_id, node.table.board.node.product_code)
    try:
        node.check_identity()
        return
    except IdentityMismatchError as error:
        problem = f"node 0x{node.node_id:02X} is {identity_text(*error.actual)}, not the table's {expected}"
    except SdoAbortError as error:
        problem = f"node 0x{node.node_id:02X} does not tell its identity ({error}), the table's is {expected}"
    if getattr(args, "force", False):
        progress(f"hilrig: warning: {problem} ({table}); writing anyway (--force)")
        return
    raise WrongBoardError(
        f"{problem} ({table}): nothing written; give that board's --table, or --force to write anyway"
    )


def silent_hint(node_id: int) -> str:
    return (
        f"is the board powered and on this bus with node id 0x{node_id:02X} "
        "(and the bit rate right)? `hilrig scan` lists the nodes that answer"
    )
