"""`hilrig scan`: which CANopen nodes are on the bus.

Two ways to be found, run together: a node's boot-up or heartbeat (on its `heartbeat_cob_id`) heard
while listening, and an answer to an SDO upload of 0x1018 sub 1 (vendor id), sent to node ids
1..127 at once at the start. Each node found is then asked for 0x1008 (device name) and 0x1018
(product code, revision) with a short timeout; a node that lacks one shows '-'.
"""

from __future__ import annotations

import argparse
import sys

from boardproto.cia301 import MAX_NODE_ID, MIN_NODE_ID
from hilrig.cli.common import (
    Command,
    add_bus_options,
    describe_bus,
    open_bus,
    positive_float,
    print_table,
    progress,
)
from hilrig.errors import NodeSilentError


def state_name(state: int | None) -> str:
    from boardproto.cia301 import NmtState

    if state is None:
        return "(no heartbeat)"
    try:
        return NmtState(state).name.lower().replace("initialising", "boot-up")
    except ValueError:
        return f"0x{state:02X}?"


def _hex(value: int | None) -> str:
    return "-" if value is None else f"0x{value:08X}"


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--listen",
        type=positive_float,
        default=1.0,
        metavar="S",
        help="seconds to listen for heartbeats and probe answers (default: 1)",
    )
    parser.add_argument(
        "--sdo-timeout",
        type=positive_float,
        default=0.5,
        metavar="S",
        help="seconds to wait for each identity read of a node found (default: 0.5)",
    )
    parser.add_argument(
        "--no-probe",
        action="store_true",
        help="only listen (send nothing): for a bus where probing is not welcome",
    )
    add_bus_options(parser)


def run(args: argparse.Namespace) -> int:
    from hilrig.apps.scan import identify, listen

    ids = range(MIN_NODE_ID, MAX_NODE_ID + 1)
    with open_bus(args) as bus:
        what = "listening" if args.no_probe else f"probing node ids {ids.start}..{ids.stop - 1} and listening"
        progress(f"scan: {what} for {args.listen:g} s on {describe_bus(args)}")
        found = listen(bus, args.listen, ids, probe=not args.no_probe)
        for number, node in enumerate(sorted(found.values(), key=lambda n: n.node_id), start=1):
            progress(f"scan: reading the identity of node 0x{node.node_id:02X} ({number}/{len(found)})")
            identify(bus, node, args.sdo_timeout)
    if not found:
        raise NodeSilentError(
            f"no CANopen node answered on {describe_bus(args)} within {args.listen:g} s; "
            "is the board powered, the bus terminated and the bit rate right? "
            "(--listen S listens longer)"
        )
    rows = [
        [
            f"0x{n.node_id:02X}",
            state_name(n.state),
            n.device_name or "-",
            _hex(n.vendor_id),
            _hex(n.product_code),
            _hex(n.revision),
        ]
        for n in sorted(found.values(), key=lambda n: n.node_id)
    ]
    print_table(rows, ["node", "state", "device name", "vendor", "product", "revision"])
    print(f"{len(found)} node{'s' if len(found) != 1 else ''} on {describe_bus(args)}", file=sys.stderr)
    return 0


COMMANDS = (
    Command(
        name="scan",
        help="find the CANopen nodes on a bus: id, state, device name, vendor/product/revision",
        description=__doc__.split("\n", 1)[1].strip() + "\n\n"
        "  hilrig scan\n"
        "  hilrig scan --interface kvaser --channel 0 --bitrate 500000 --listen 3",
        configure=configure,
        run=run,
    ),
)
