"""`hilrig lss number|set|identify`: give new boards their node ids over LSS (CiA 305).

`number` finds the boards that have no node id yet (fastscan: the vendor, product and revision
come from the table, the serial number is scanned), gives them ids from --first-id on, stores
each (LSS store configuration), waits for each one's boot-up and verifies it by reading its
identity (0x1018) back over SDO. Boards are numbered in the order of their serial numbers, or,
with --chain, in the order of a modular robot's chain: each module joins LSS only once its
upstream neighbour has an id (the enable line of `hilrig.wire.lss`). `set` gives one board,
named by its serial number, an id (a board that had one takes it at its next reset
communication: `hilrig nmt reset-comm`). `identify` says whether any board without an id is on
the bus.
"""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from boardproto.cia305 import NODE_ID_UNCONFIGURED
from hilrig.cli.common import (
    Command,
    add_bus_options,
    add_table_option,
    describe_bus,
    load_table,
    node_id,
    open_bus,
    positive_float,
    positive_int,
    print_table,
    progress,
)
from hilrig.errors import NodeSilentError

if TYPE_CHECKING:
    from hilrig.wire.lss import LssAddress, LssCommissioner

DEFAULT_LSS_TIMEOUT_S = 0.2
DEFAULT_BOOT_TIMEOUT_S = 5.0


def serial_number(text: str) -> int:
    """A serial number: decimal or 0x hex, 32 bits."""
    try:
        value = int(text, 0)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number (decimal or 0x hex), got {text!r}") from None
    if not 0 <= value <= 0xFFFF_FFFF:
        raise argparse.ArgumentTypeError(f"expected 0..0xFFFFFFFF, got {text!r}")
    return value


def configure(parser: argparse.ArgumentParser) -> None:
    actions = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    number = actions.add_parser("number", help="find boards without an id, number them, store, verify")
    number.add_argument("--first-id", type=node_id, default=1, help="the first node id given (default: 1)")
    number.add_argument(
        "--count", type=positive_int, default=None, help="stop after this many boards (default: all found)"
    )
    number.add_argument(
        "--chain",
        action="store_true",
        help="a modular robot wired as a chain (enable lines): number it in chain order, asking again "
        "for the next module after each boot-up",
    )
    number.add_argument("--no-store", action="store_true", help="do not store the ids (lost at power-off)")
    set_ = actions.add_parser("set", help="give the board with this serial number a node id, stored")
    set_.add_argument("node_id", type=node_id, metavar="NODE_ID", help="the node id to give, 1..127")
    set_.add_argument(
        "--serial", type=serial_number, required=True, help="the board's serial number (0x1018:4)"
    )
    set_.add_argument("--no-store", action="store_true", help="do not store the id")
    actions.add_parser("identify", help="is any board without a node id on the bus?")
    for sub in (number, set_, actions.choices["identify"]):
        sub.add_argument(
            "--timeout",
            type=positive_float,
            default=DEFAULT_LSS_TIMEOUT_S,
            metavar="S",
            help="seconds to wait for each LSS answer; silence means no "
            f"(default: {DEFAULT_LSS_TIMEOUT_S:g})",
        )
        sub.add_argument(
            "--boot-timeout",
            type=positive_float,
            default=DEFAULT_BOOT_TIMEOUT_S,
            metavar="S",
            help="seconds to wait for a board's boot-up and SDO answers "
            f"(default: {DEFAULT_BOOT_TIMEOUT_S:g})",
        )
        add_table_option(sub)
        add_bus_options(sub)


def _product(args: argparse.Namespace) -> LssAddress:
    from hilrig.wire.lss import LssAddress

    node = load_table(args).board.node
    return LssAddress.of_product(node.vendor_id, node.product_code, node.revision)


def run(args: argparse.Namespace) -> int:
    from hilrig.wire.lss import commissioner_on

    product = _product(args)
    with open_bus(args) as bus, commissioner_on(bus, timeout_s=args.timeout) as lss:
        if args.action == "identify":
            return _identify(args, lss)
        if args.action == "set":
            return _set(args, lss, product)
        return _number(args, lss, product)


def _identify(args: argparse.Namespace, lss: LssCommissioner) -> int:
    if lss.identify_non_configured():
        print(f"a board without a node id is on {describe_bus(args)} (`hilrig lss number` numbers it)")
    else:
        print(f"no board without a node id answered on {describe_bus(args)} within {args.timeout:g} s")
    return 0


def _verified(lss: LssCommissioner, node: int, address: LssAddress, timeout_s: float) -> str:
    read = lss.read_identity(node, timeout_s)
    if read != address:
        raise NodeSilentError(f"node 0x{node:02X}: 0x1018 over SDO reads {read}, LSS found {address}")
    return "0x1018 matches"


def _set(args: argparse.Namespace, lss: LssCommissioner, product: LssAddress) -> int:
    from hilrig.wire.lss import LssAddress

    address = LssAddress(product.vendor_id, product.product_code, product.revision, args.serial)
    lss.select(address)
    had = lss.inquire_node_id()
    with lss.boot_up_watch(args.node_id) as watch:
        lss.assign(args.node_id, store=not args.no_store)
        given = (
            f"serial 0x{args.serial:08X}: node id 0x{args.node_id:02X} {'set' if args.no_store else 'stored'}"
        )
        if had == args.node_id:  # a configured node boots only at its next reset communication
            print(f"{given}; it had it already")
            return 0
        if had != NODE_ID_UNCONFIGURED:
            print(
                f"{given}; it keeps 0x{had:02X} until its next reset communication "
                f"(`hilrig nmt reset-comm 0x{had:02X}`)"
            )
            return 0
        watch.wait(args.boot_timeout)
    check = _verified(lss, args.node_id, address, args.boot_timeout)
    print(f"serial 0x{args.serial:08X}: node id 0x{args.node_id:02X}, booted, {check}")
    return 0


def _number(args: argparse.Namespace, lss: LssCommissioner, product: LssAddress) -> int:
    from hilrig.wire import lss as lss_module

    order = "chain order" if args.chain else "serial-number order"
    progress(
        f"lss: numbering boards without a node id on {describe_bus(args)} from 0x{args.first_id:02X} "
        f"in {order} ({product} from the table)"
    )
    rows: list[list[str]] = []

    def found(node: int, address: LssAddress) -> None:
        check = _verified(lss, node, address, args.boot_timeout)
        stored = "no" if args.no_store else "yes"
        rows.append([f"0x{node:02X}", f"0x{address.serial_number:08X}", stored, check])
        progress(f"lss: serial 0x{address.serial_number:08X} is node 0x{node:02X} ({check})")

    settle = lss_module.CHAIN_SETTLE_ASKS if args.chain else 1
    numbered = lss.number_chain(
        product,
        first_id=args.first_id,
        count=args.count,
        store=not args.no_store,
        boot_timeout_s=args.boot_timeout,
        on_module=found,
        settle_asks=settle,
    )
    if not numbered:
        raise NodeSilentError(
            f"no board without a node id answered fastscan on {describe_bus(args)} "
            f"({product}); `hilrig scan` lists the boards that have one"
        )
    print_table(rows, ["node", "serial", "stored", "identity over SDO"])
    last = numbered[-1][0]
    print(
        f"{len(numbered)} board{'s' if len(numbered) != 1 else ''} numbered "
        f"0x{args.first_id:02X}..0x{last:02X} in {order} on {describe_bus(args)}",
        file=sys.stderr,
    )
    return 0


COMMANDS = (
    Command(
        name="lss",
        help="give new boards node ids over LSS (CiA 305): number them, in chain order too",
        description=__doc__.split("\n\n", 1)[1].strip() + "\n\n"
        "  hilrig lss identify                     # any board without an id?\n"
        "  hilrig lss number                       # ids 1, 2, ... by serial number, stored, verified\n"
        "  hilrig lss number --chain --first-id 1  # a robot's modules in chain order\n"
        "  hilrig lss set 5 --serial 0x00000031    # one board by its serial number",
        configure=configure,
        run=run,
    ),
)
