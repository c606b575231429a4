"""`hilrig monitor`: every frame on the bus, decoded with this board's names, live.

One row per CAN id, as `cantools monitor` shows a bus: the PDOs by their DBC message with each
field's value and unit (the board's names for enum and flag values), the CiA 301 services in
words (NMT, SYNC, EMCY with its class and the board's name for its code, heartbeat state, SDO
transfers: upload or download, index:sub by the table's name, the value with its unit, the
abort's text);
beside each its count, rate and the age of its latest frame. On a terminal the table is redrawn
in place a few times a second; piped, it is printed once at the end. It only listens: nothing is
sent, so it sits beside any master (the rig, a PLC, python-canopen) without changing the bus.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

from hilrig.cli.common import (
    Command,
    add_bus_options,
    add_table_option,
    dbc_path,
    describe_bus,
    existing_file,
    load_dbc,
    load_table,
    node_id,
    open_bus,
    positive_float,
    positive_int,
    progress,
)
from hilrig.resources import DBC_HINT

if TYPE_CHECKING:
    from hilrig.session.canbus import Message

REDRAW_S = 0.25
"""How often a terminal's table is redrawn."""
COLUMNS = (["id", "frames", "per s", "age s", "decoded"], frozenset({1, 2, 3}))


@dataclass
class Seen:
    """What the monitor keeps of one CAN id: how many frames, when, and the latest in words."""

    frames: int
    first: float
    last: float
    text: str


def configure(parser: argparse.ArgumentParser) -> None:
    from hilrig.cli.files import sniff_dbc

    parser.add_argument(
        "--duration",
        type=positive_float,
        default=None,
        metavar="S",
        help="stop after S seconds (default: until Ctrl-C)",
    )
    parser.add_argument(
        "--count",
        type=positive_int,
        default=None,
        metavar="N",
        help="stop after N frames (default: until Ctrl-C or --duration)",
    )
    parser.add_argument(
        "-n",
        "--node-id",
        type=node_id,
        default=None,
        help="the node whose PDOs the DBC decodes (default: the table's)",
    )
    parser.add_argument(
        "--dbc",
        type=existing_file("DBC", DBC_HINT, suffixes=(".dbc",), sniff=sniff_dbc),
        default=None,
        help="the DBC (default: the table's: build/protocol/board.dbc in a checkout)",
    )
    add_table_option(parser)
    add_bus_options(parser)


def rows(seen: dict[tuple[int, bool], Seen], now: float) -> list[list[str]]:
    """The table: one row per CAN id, in id order."""
    table = []
    for (can_id, extended), entry in sorted(seen.items()):
        span = entry.last - entry.first
        rate = f"{(entry.frames - 1) / span:.1f}" if entry.frames > 1 and span > 0 else "-"
        name = f"0x{can_id:08X}" if extended else f"0x{can_id:03X}"
        table.append([name, str(entry.frames), rate, f"{max(0.0, now - entry.last):.1f}", entry.text])
    return table


def run(args: argparse.Namespace) -> int:
    from hilrig.cli.record import FrameDecoder, sdo_dictionary
    from hilrig.cli.watch import Screen
    from hilrig.session.buslog import NodeDbc

    table = load_table(args)
    node = args.node_id if args.node_id is not None else table.board.node.default_node_id
    decoder = FrameDecoder(
        NodeDbc(load_dbc(dbc_path(args)), table, node), table, node, set(), od=sdo_dictionary(args, node)
    )
    screen = Screen(sys.stdout, in_place=sys.stdout.isatty())
    seen: dict[tuple[int, bool], Seen] = {}
    errors = 0
    started = time.monotonic()
    deadline = started + args.duration if args.duration is not None else None
    where = describe_bus(args)

    def draw() -> None:
        title = f"monitor: {where}, {time.monotonic() - started:.1f} s, error frames {errors}"
        screen.draw(title, rows(seen, time.time()), headers=COLUMNS)

    with open_bus(args) as bus:
        where = describe_bus(args)  # now what python-can's configuration resolved to
        progress(f"monitor: listening on {where} (Ctrl-C ends)")
        next_draw = started + REDRAW_S
        try:
            frames = 0
            while (deadline is None or time.monotonic() < deadline) and frames != args.count:
                message = bus.recv(timeout=REDRAW_S)
                if message is not None:
                    frames += 1
                    errors += _take(message, decoder, seen)
                now = time.monotonic()
                if screen.in_place and now >= next_draw:
                    draw()
                    next_draw = now + REDRAW_S
        except KeyboardInterrupt:
            pass  # the person is done looking: the last table below
    draw()
    return 0


def _take(message: Message, decoder: object, seen: dict[tuple[int, bool], Seen]) -> int:
    """Count a frame under its id; 1 for an error frame (counted, not listed)."""
    if message.is_error_frame:
        return 1
    text = decoder.describe(message) or ""  # type: ignore[attr-defined]
    key = (message.arbitration_id, message.is_extended_id)
    stamp = message.timestamp or time.time()
    entry = seen.get(key)
    if entry is None:
        seen[key] = Seen(1, stamp, stamp, text)
    else:
        entry.frames += 1
        entry.last = stamp
        entry.text = text
    return 0


COMMANDS = (
    Command(
        name="monitor",
        help="every frame on the bus live, one row per CAN id, decoded with this board's names",
        description=(__doc__ or "").split("\n\n", 1)[1].strip() + "\n\n"
        "  hilrig monitor                          # python-can's configured bus, until Ctrl-C\n"
        "  hilrig monitor -c can0 -b 1M -n 0x21    # the board at node 0x21\n"
        "  hilrig monitor --duration 5 | less      # piped: the table once, after 5 s\n"
        "  hilrig monitor --count 1000             # the first 1000 frames",
        configure=configure,
        run=run,
    ),
)
