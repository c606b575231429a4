"""`hilrig nmt start|stop|preop|reset|reset-comm [NODE|all]`: network management by hand.

Sends the NMT command (`hilrig.wire.master`) to one node, or to every node (`all`, node id 0
on the wire). With --wait, for one node, it then waits for the state change to show: the
boot-up message after a reset, else a heartbeat in the new state, and says how long it took.
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import TYPE_CHECKING

from boardproto.cia301 import NMT_ALL_NODES, NmtCommand, NmtState
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
)
from hilrig.errors import NodeSilentError

if TYPE_CHECKING:
    from hilrig.wire.master import HeartbeatWatch

ACTIONS: dict[str, NmtCommand] = {
    "start": NmtCommand.START,
    "stop": NmtCommand.STOP,
    "preop": NmtCommand.ENTER_PRE_OPERATIONAL,
    "reset": NmtCommand.RESET_NODE,
    "reset-comm": NmtCommand.RESET_COMMUNICATION,
}
"""The command line's words for the CiA 301 NMT commands."""

DEFAULT_WAIT_S = 3.0


def nmt_target(text: str) -> int:
    """'all' -> 0, else a node id 1..127."""
    return NMT_ALL_NODES if text.lower() == "all" else node_id(text)


def _state_name(state: int) -> str:
    from hilrig.cli.scan import state_name

    return state_name(state)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("action", choices=list(ACTIONS), metavar="{" + ",".join(ACTIONS) + "}")
    parser.add_argument(
        "node",
        nargs="?",
        type=nmt_target,
        default=None,
        metavar="NODE|all",
        help="node id 1..127 (decimal or 0x hex), or all (default: the table's, 0x10)",
    )
    parser.add_argument(
        "-w",
        "--wait",
        action="store_true",
        help="wait for the node to show the change: its boot-up after a reset, else a heartbeat "
        "in the new state (needs its heartbeat producer time, 0x1017, set)",
    )
    parser.add_argument(
        "--timeout",
        type=positive_float,
        default=DEFAULT_WAIT_S,
        metavar="S",
        help=f"--wait: seconds to wait (default: {DEFAULT_WAIT_S:g})",
    )
    add_table_option(parser)
    add_bus_options(parser)


def run(args: argparse.Namespace) -> int:
    from hilrig.wire.master import BusMaster

    command = ACTIONS[args.action]
    target = args.node if args.node is not None else load_table(args).board.node.default_node_id
    if args.wait and target == NMT_ALL_NODES:
        raise UsageError(
            "--wait needs one node: after an NMT command to all, each node answers in its own time "
            "(`hilrig scan` lists their states)"
        )
    addressee = "all nodes" if target == NMT_ALL_NODES else f"node 0x{target:02X}"
    with open_bus(args) as bus, BusMaster(bus) as master:
        watch = master.watch_heartbeat(target) if args.wait else None
        since = len(watch.heard) if watch is not None else 0
        sent_at = time.monotonic()
        master.nmt(command, target)
        if watch is None:
            print(f"NMT {args.action} sent to {addressee} on {describe_bus(args)}")
            return 0
        expected = NmtState.INITIALISING if _is_reset(command) else command.resulting_state
        heard = watch.wait_for(expected, since, args.timeout)
    if heard is None:
        raise NodeSilentError(_silence(target, args.action, expected, watch, args.timeout))
    after = f"{heard.at - sent_at:.2f} s after NMT {args.action}"
    if expected is NmtState.INITIALISING:
        print(f"node 0x{target:02X}: boot-up {after}, now {_state_name(command.resulting_state)}")
    else:
        print(f"node 0x{target:02X}: {_state_name(expected)}, {after}")
    sys.stdout.flush()
    return 0


def _is_reset(command: NmtCommand) -> bool:
    return command in (NmtCommand.RESET_NODE, NmtCommand.RESET_COMMUNICATION)


def _silence(target: int, action: str, expected: NmtState, watch: HeartbeatWatch, timeout_s: float) -> str:
    what = "boot-up" if expected is NmtState.INITIALISING else f"heartbeat showing {_state_name(expected)}"
    if watch.heard:
        last = f"last heard: {_state_name(watch.heard[-1].state)}"
    else:
        last = (
            "heard nothing from it: is it on this bus with this node id, and its heartbeat "
            f"producer time (0x1017) set? `hilrig sdo read 0x1017 -n 0x{target:02X}`"
        )
    return f"node 0x{target:02X}: no {what} within {timeout_s:g} s of NMT {action}; {last}"


COMMANDS = (
    Command(
        name="nmt",
        help="send an NMT command (start, stop, preop, reset, reset-comm) to a node or all",
        description=__doc__.split("\n\n", 1)[1].strip() + "\n\n"
        "  hilrig nmt start                  # the table's node (0x10) to operational\n"
        "  hilrig nmt start 0x10 --wait      # ... and wait for its heartbeat to say so\n"
        "  hilrig nmt reset all              # every node on the bus\n"
        "  hilrig nmt reset-comm 5 -w --timeout 5",
        configure=configure,
        run=run,
    ),
)
