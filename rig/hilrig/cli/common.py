"""What every `hilrig` command shares: the command registry entry, the bus and node options,
opening the bus with errors in words, and value formatting.

Heavy imports (python-can, canopen, cantools) happen inside the functions that need them, so
`hilrig --help` and `hilrig fields` stay quick (each import costs seconds in the micro-VM).
"""

from __future__ import annotations

import argparse
import contextlib
import difflib
import errno
import sys
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Self, TextIO

from boardproto.table import BitSet, ValueEnum
from hilrig.errors import BusUnavailableError, FieldNameError, RigError
from hilrig.table import DEFAULT_TABLE_PATH, ObjectEntry, RigTable

if TYPE_CHECKING:
    import can

    from hilrig.node import BoardNode

REPO = Path(__file__).resolve().parents[3]
DEFAULT_EDS = REPO / "build" / "protocol" / "board.eds"
DEFAULT_DBC = REPO / "build" / "protocol" / "board.dbc"
DEFAULT_INTERFACE = "socketcan"
DEFAULT_CHANNEL = "vcan0"
MAX_NODE_ID = 127


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
def node_id(text: str) -> int:
    """'16' or '0x10' -> 16; 1..127."""
    try:
        value = int(text, 0)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected a node id 1..{MAX_NODE_ID} (decimal or 0x hex, e.g. 0x10), got {text!r}"
        ) from None
    if not 1 <= value <= MAX_NODE_ID:
        raise argparse.ArgumentTypeError(
            f"expected a node id 1..{MAX_NODE_ID} (decimal or 0x hex, e.g. 0x10), got {text}"
        )
    return value


def interface_name(text: str) -> str:
    """A python-can interface name; unknown ones are refused with the close matches."""
    from can.interfaces import VALID_INTERFACES

    if text in VALID_INTERFACES:
        return text
    matches = difflib.get_close_matches(text, sorted(VALID_INTERFACES), n=3, cutoff=0.5)
    hint = f"did you mean {' or '.join(matches)}? " if matches else ""
    raise argparse.ArgumentTypeError(
        f"unknown python-can interface {text!r}; {hint}known: {', '.join(sorted(VALID_INTERFACES))}"
    )


def positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of seconds > 0, got {text!r}") from None
    if not value > 0.0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text}")
    return value


def positive_int(text: str) -> int:
    try:
        value = int(text, 0)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number > 0, got {text!r}") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"expected a whole number > 0, got {text}")
    return value


def existing_file(what: str, hint: str) -> Callable[[str], Path]:
    def check(text: str) -> Path:
        path = Path(text)
        if not path.is_file():
            raise argparse.ArgumentTypeError(f"{what} {text} does not exist; {hint}")
        return path

    return check


# --- Option groups ---------------------------------------------------------------------
def add_table_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--table",
        type=existing_file("board table", "pass --table PATH/board.toml"),
        default=DEFAULT_TABLE_PATH,
        metavar="TOML",
        help="the board field table (default: protocol/board.toml of this checkout)",
    )


def add_bus_options(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("bus (any python-can interface)")
    group.add_argument(
        "-i",
        "--interface",
        type=interface_name,
        default=DEFAULT_INTERFACE,
        help=f"python-can interface: socketcan, pcan, kvaser, slcan, vector... "
        f"(default: {DEFAULT_INTERFACE})",
    )
    group.add_argument(
        "-c",
        "--channel",
        default=DEFAULT_CHANNEL,
        help=f"channel of that interface: vcan0, can0, PCAN_USBBUS1, /dev/ttyACM0@115200... "
        f"(default: {DEFAULT_CHANNEL})",
    )
    group.add_argument(
        "-b",
        "--bitrate",
        type=positive_int,
        default=None,
        help="bit rate in bit/s for adapters that set it (pcan, kvaser, slcan); "
        "SocketCAN takes it from `ip link`",
    )


def add_node_options(parser: argparse.ArgumentParser, *, sdo_timeout_s: float = 1.0) -> None:
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
        type=existing_file("EDS", "build it with `make build` or pass --eds FILE"),
        default=DEFAULT_EDS,
        help="the board's EDS (default: build/protocol/board.eds)",
    )
    group.add_argument(
        "--sdo-timeout",
        type=positive_float,
        default=sdo_timeout_s,
        metavar="S",
        help=f"seconds to wait for each SDO answer (default: {sdo_timeout_s:g})",
    )
    add_table_option(parser)


# --- Table and values ------------------------------------------------------------------
def load_table(args: argparse.Namespace) -> RigTable:
    return RigTable.load(args.table)


def check_names(table: RigTable, names: list[str]) -> list[ObjectEntry]:
    """The entries of `names`; a name not in the table is a usage error with close matches."""
    try:
        return [table.entry(name) for name in names]
    except FieldNameError as error:
        raise UsageError(f"{error} (`hilrig fields` lists every name)") from None


def resolved_node_id(args: argparse.Namespace, table: RigTable) -> int:
    return args.node_id if args.node_id is not None else table.board.node.default_node_id


def format_value(value: float | None, named: ValueEnum | BitSet | None = None) -> str:
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
    return f"{args.interface} channel {args.channel}"


@contextlib.contextmanager
def open_bus(args: argparse.Namespace, **kwargs: object) -> Iterator[can.BusABC]:
    """The python-can bus of --interface/--channel/--bitrate; errors become one line."""
    import can

    options: dict[str, object] = dict(kwargs)
    if args.bitrate is not None:
        options["bitrate"] = args.bitrate
    try:
        bus = can.Bus(interface=args.interface, channel=args.channel, **options)
    except (can.CanError, OSError, ValueError, ImportError) as error:
        raise BusUnavailableError(
            f"cannot open {describe_bus(args)}: {one_line(error)}{_bus_hint(args, error)}"
        ) from error
    from hilrig.netns import deepen_receive_queue

    deepen_receive_queue(bus)  # a recorder or watcher descheduled for a moment loses nothing
    try:
        yield bus
    finally:
        bus.shutdown()


def _bus_hint(args: argparse.Namespace, error: BaseException) -> str:
    code = _errno_of(error)
    if args.interface == "socketcan":
        if code == errno.EAFNOSUPPORT:
            return (
                "; this kernel has no SocketCAN: run inside `tools/with-vcan -- ...` or pick "
                "another --interface"
            )
        if code == errno.ENODEV or "No such device" in str(error):
            return f"; no interface {args.channel} here: `ip link show` lists them, `make vcan` creates vcan0"
        return ""
    return f"; is the {args.interface} adapter plugged in and its driver installed?"


def _errno_of(error: BaseException | None) -> int | None:
    while error is not None:
        if isinstance(error, OSError) and error.errno is not None:
            return error.errno
        for attr in ("error_code",):
            code = getattr(error, attr, None)
            if isinstance(code, int):
                return code
        error = error.__cause__ or error.__context__
    return None


def one_line(error: BaseException) -> str:
    return " ".join(str(error).split()) or type(error).__name__


@contextlib.contextmanager
def board_node(args: argparse.Namespace, bus: can.BusABC, table: RigTable) -> Iterator[BoardNode]:
    from hilrig.node import BoardNode

    node = BoardNode(bus, resolved_node_id(args, table), args.eds, table, sdo_timeout_s=args.sdo_timeout)
    try:
        yield node
    finally:
        node.close()


def silent_hint(node_id: int) -> str:
    return (
        f"is the board powered and on this bus with node id 0x{node_id:02X} "
        "(and the bit rate right)? `hilrig scan` lists the nodes that answer"
    )


class SyncProducer:
    """Sends SYNC (with counter 1..240) every `period_s` from a thread, until stopped."""

    def __init__(self, send: Callable[[int], None], period_s: float) -> None:
        self._send = send
        self._period_s = period_s
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="sync-producer", daemon=True)
        self.error: BaseException | None = None

    def __enter__(self) -> Self:
        self._thread.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self._stop.set()
        self._thread.join()

    def _run(self) -> None:
        counter = 0
        while not self._stop.wait(self._period_s):
            counter = counter % 240 + 1
            try:
                self._send(counter)
            except Exception as error:  # surfaced by the main loop
                self.error = error
                return
