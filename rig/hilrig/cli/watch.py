"""`hilrig watch`: a live table of the fields the node streams in its TPDOs, and its EMCYs.

The table is redrawn in place with ANSI cursor movement (no curses). Fields not carried by any
enabled TPDO are read by SDO at each refresh instead. Under the table, the node's latest EMCYs,
each with its CiA 301 class and the board's name for its code. In lockstep the firmware runs a control
cycle and sends its synchronous TPDOs only on SYNC, and a node without a master stays
pre-operational (no PDOs at all): for bring-up of a board on its own, `--nmt-start` puts it
operational and `--sync-period-ms P` makes this command the SYNC producer.
"""

from __future__ import annotations

import argparse
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, TextIO

from hilrig.cli.common import (
    LIVE_VIEWER_HELP,
    Command,
    Named,
    add_node_options,
    board_node,
    check_names,
    dbc_path,
    format_unit,
    format_value,
    live_sink,
    load_dbc,
    load_table,
    open_bus,
    positive_float,
    positive_int,
    print_table,
    progress,
    silent_hint,
    value_names,
)
from hilrig.errors import NodeSilentError, RigError, SdoTimeoutError
from hilrig.table import ObjectEntry

if TYPE_CHECKING:
    from hilrig.apps.log_trace import LiveBusTrace
    from hilrig.engine.realtime import SyncProducer
    from hilrig.table import RigTable
    from hilrig.wire.node import BoardNode, EmcyError, EmcyRecord
    from hilrig.wire.transport import PdoLayout

CLEAR_LINE = "\x1b[2K"
EMCY_LINES = 5  # the latest EMCYs shown under the table


def cursor_up(lines: int) -> str:
    """ANSI: move to the start of the line `lines` above."""
    return f"\x1b[{lines}F" if lines > 0 else "\r"


@dataclass
class Reading:
    value: float | int | None = None
    source: str = "-"
    updates: int = 0


class Board:
    """Latest value of each watched field, fed by the TPDO callback (receive thread)."""

    def __init__(self, entries: list[ObjectEntry], named: dict[str, Named] | None = None) -> None:
        self.entries = entries
        self.named = named or {}  # names of the values of fields that have them (board.toml)
        self.readings = {e.name: Reading() for e in entries}
        self.emcy: list[tuple[float, EmcyRecord]] = []  # (wall time, EMCY), the latest EMCY_LINES
        self.started = time.time()
        self._lock = threading.Lock()
        self.changed = threading.Condition(self._lock)

    def on_tpdo(self, pdo: PdoLayout, values: dict[str, float | int]) -> None:
        with self._lock:
            for name, value in values.items():
                reading = self.readings.get(name)
                if reading is not None:
                    reading.value, reading.source = value, pdo.label
                    reading.updates += 1
            self.changed.notify_all()

    def on_emcy(self, error: EmcyError) -> None:
        """An EMCY the node sent (canopen's receive thread)."""
        from hilrig.wire.node import EmcyRecord  # canopen's: loaded by the watch, not by `hilrig --help`

        record = EmcyRecord(error.code, error.register, bytes(error.data), cycle=0, time_s=0.0)
        with self._lock:
            self.emcy = [*self.emcy, (error.timestamp, record)][-EMCY_LINES:]

    def emcy_lines(self) -> list[str]:
        with self._lock:
            return [f"{record.summary} at {at - self.started:.1f} s" for at, record in self.emcy]

    def store(self, name: str, value: float, source: str) -> None:
        with self._lock:
            reading = self.readings[name]
            reading.value, reading.source = value, source
            reading.updates += 1

    def missing(self) -> list[str]:
        with self._lock:
            return [name for name, r in self.readings.items() if r.value is None]

    def wait_streamed(self, timeout_s: float, polled: list[str]) -> bool:
        """Wait until every field but the `polled` ones has a value from a TPDO."""
        with self._lock:
            return self.changed.wait_for(
                lambda: all(r.value is not None for n, r in self.readings.items() if n not in polled),
                timeout_s,
            )

    def rows(self) -> list[list[str]]:
        with self._lock:
            return [
                [
                    e.name,
                    format_value(self.readings[e.name].value, self.named.get(e.name)),
                    format_unit(e.unit),
                    self.readings[e.name].source,
                    str(self.readings[e.name].updates),
                ]
                for e in self.entries
            ]


WATCH_COLUMNS = (["name", "value", "unit", "via", "updates"], frozenset({1, 4}))
"""The table's column names, and those set right."""


class Screen:
    """Draws the table; on a terminal each frame overwrites the previous one."""

    def __init__(self, out: TextIO, in_place: bool) -> None:
        self.out = out
        self.in_place = in_place
        self._lines = 0

    def draw(
        self,
        title: str,
        rows: list[list[str]],
        notes: list[str] | None = None,
        headers: tuple[list[str], frozenset[int]] = WATCH_COLUMNS,
    ) -> None:
        """The title, the rows under `headers` (their names, and the columns set right), the notes."""
        from io import StringIO

        text = StringIO()
        text.write(title + "\n")
        print_table(rows, headers[0], out=text, right=headers[1])
        lines = text.getvalue().splitlines() + (notes or [])
        if self.in_place:
            prefix = cursor_up(self._lines) if self._lines else ""
            self.out.write(prefix + "".join(f"{CLEAR_LINE}{line}\n" for line in lines))
        else:
            if self._lines:
                self.out.write("\n")
            self.out.write("\n".join(lines) + "\n")
        self.out.flush()
        self._lines = len(lines)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "names",
        nargs="*",
        metavar="NAME",
        help="fields to show (default: everything the enabled TPDOs carry)",
    )
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument(
        "--once",
        action="store_true",
        help="wait until every field has a value, print the table once, exit (scripts)",
    )
    mode.add_argument("--count", type=positive_int, metavar="N", help="print N refreshes, then exit")
    parser.add_argument(
        "--interval",
        type=positive_float,
        default=0.2,
        metavar="S",
        help="seconds between refreshes (default: 0.2)",
    )
    parser.add_argument(
        "--timeout",
        type=positive_float,
        default=5.0,
        metavar="S",
        help="--once: seconds to wait for every field (default: 5)",
    )
    parser.add_argument(
        "--sync-period-ms",
        type=positive_float,
        metavar="P",
        help="send SYNC every P ms: for a board with no master (in lockstep the "
        "firmware sends TPDOs only on SYNC)",
    )
    parser.add_argument(
        "--nmt-start",
        action="store_true",
        help="send NMT start first (a node with no master stays pre-operational and sends no PDOs)",
    )
    parser.add_argument(
        "--pdo-from-eds",
        action="store_true",
        help="take the TPDO mapping from the EDS instead of reading it from the node",
    )
    parser.add_argument(
        "--viewer",
        action="append",
        type=live_sink,
        default=None,
        metavar="WHERE",
        help="also stream the node's PDOs live to Rerun, decoded with the DBC (build/protocol/"
        "board.dbc) on the wall-clock timeline (repeatable): " + LIVE_VIEWER_HELP,
    )
    add_node_options(parser)


def run(args: argparse.Namespace) -> int:
    from boardproto.cia301 import NmtCommand

    table = load_table(args)
    requested = check_names(table, args.names)
    with open_bus(args) as bus, board_node(args, bus, table) as node:
        try:
            node.read_pdo_configuration(from_node=not args.pdo_from_eds)
        except SdoTimeoutError as error:
            raise NodeSilentError(f"{error}; {silent_hint(node.node_id)}") from error
        streamed = {n for p in node.tpdos.values() if p.enabled for n in p.names}
        entries = requested or [
            table.entry(n)
            for p in sorted(node.tpdos.values(), key=lambda p: p.number)
            if p.enabled
            for n in p.names
        ]
        polled = [e.name for e in entries if e.name not in streamed]
        board = Board(entries, value_names(table))
        node.on_tpdo(board.on_tpdo)
        node.on_emcy(board.on_emcy)
        live = _live_trace(args, node, table) if args.viewer else None
        if args.nmt_start:
            node.nmt(NmtCommand.START)
        screen = Screen(sys.stdout, in_place=sys.stdout.isatty() and not args.once and args.count != 1)
        from hilrig.engine.realtime import SyncProducer

        send_sync = node.send_sync if live is None else _traced(node.send_sync, live)
        sync = SyncProducer(send_sync, args.sync_period_ms / 1e3) if args.sync_period_ms else None
        if sync is not None:
            sync.__enter__()
        try:
            return _loop(args, node, board, screen, polled, sync)
        finally:
            if sync is not None:
                sync.__exit__(None, None, None)
            if live is not None:
                notifier = node.network.notifier
                if notifier is not None:
                    notifier.remove_listener(live)
                live.stop()


def _traced(send_sync: Callable[[int], None], live: LiveBusTrace) -> Callable[[int], None]:
    """Our own SYNCs into the live trace too (a bus does not hand a sender its own frames),
    so it can group the TPDOs into cycles."""
    from boardproto.cia301 import SYNC_COB_ID

    def send(counter: int) -> None:
        send_sync(counter)
        live.on_sent(SYNC_COB_ID, bytes([counter]))

    return send


def _live_trace(args: argparse.Namespace, node: BoardNode, table: RigTable) -> LiveBusTrace:
    """The node's frames into a live Rerun trace, from canopen's own receive thread."""
    from hilrig.apps.log_trace import LiveBusTrace
    from hilrig.session.buslog import NodeDbc

    dbc = NodeDbc(load_dbc(dbc_path(args)), table, node.node_id)
    progress("watch: streaming live to " + ", ".join(map(str, args.viewer)) + " (importing rerun-sdk)")
    live = LiveBusTrace(args.viewer, dbc, table, node.node_id, name=f"watch-node-{node.node_id}")
    if live.tracer.web_url is not None:
        progress(f"watch: web viewer at {live.tracer.web_url}")
    assert node.network.notifier is not None  # BoardNode connected the network
    node.network.notifier.add_listener(live)
    return live


def _title(args: argparse.Namespace, node: BoardNode, started: float) -> str:
    state = node.last_heartbeat.name if node.last_heartbeat is not None else "no heartbeat yet"
    sync = f", SYNC every {args.sync_period_ms:g} ms" if args.sync_period_ms else ""
    stop = "" if args.once or args.count else "  (Ctrl-C to stop)"
    return (
        f"node 0x{node.node_id:02X} {state} on {args.interface} {args.channel}{sync}, "
        f"{time.monotonic() - started:.1f} s{stop}"
    )


def _loop(
    args: argparse.Namespace,
    node: BoardNode,
    board: Board,
    screen: Screen,
    polled: list[str],
    sync: SyncProducer | None,
) -> int:
    started = time.monotonic()
    frames = 0
    stop = threading.Event()
    while True:
        if args.once:
            board.wait_streamed(args.timeout, polled)
        else:
            stop.wait(args.interval)
        if sync is not None and sync.error is not None:
            raise RigError(f"sending SYNC failed: {sync.error}")
        for name in polled:
            try:
                board.store(name, node.read(name), "SDO")
            except SdoTimeoutError as error:
                raise NodeSilentError(f"{error}; {silent_hint(node.node_id)}") from error
        screen.draw(_title(args, node, started), board.rows(), board.emcy_lines())
        frames += 1
        if args.once:
            missing = board.missing()
            if missing:
                hint = (
                    ""
                    if args.sync_period_ms and args.nmt_start
                    else "; is the node operational (--nmt-start) and is anything sending SYNC "
                    "(--sync-period-ms 10)?"
                )
                raise NodeSilentError(f"no TPDO with {', '.join(missing)} within {args.timeout:g} s{hint}")
            return 0
        if args.count is not None and frames >= args.count:
            return 0


COMMANDS = (
    Command(
        name="watch",
        help="live table of the fields the node streams (TPDO), refreshed in place",
        description=__doc__.split("\n", 1)[1].strip() + "\n\n"
        "  hilrig watch                                 # everything the TPDOs carry\n"
        "  hilrig watch motor_velocity joint_torque     # just these\n"
        "  hilrig watch --nmt-start --sync-period-ms 10 # a board with no master\n"
        "  hilrig watch --once                          # one table, for scripts",
        configure=configure,
        run=run,
    ),
)
