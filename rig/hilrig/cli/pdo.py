"""`hilrig pdo apply PROFILE`: write one of the table's PDO profiles to a board and store it."""

from __future__ import annotations

import argparse

from hilrig.cli.common import (
    Command,
    UsageError,
    add_node_options,
    board_node,
    load_table,
    open_bus,
    progress,
    silent_hint,
)
from hilrig.errors import NodeSilentError, SdoTimeoutError


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("action", choices=["apply"], help="apply: write the profile and store it")
    parser.add_argument("profile", metavar="PROFILE", help="a [[pdo_profile]] of the table: full, lean...")
    add_node_options(parser, writes=True)


def run(args: argparse.Namespace) -> int:
    """0 once the node has the profile and stored it; a refused write fails with its abort code."""
    from boardproto import UnknownNameError
    from boardproto.cia301 import transmission_text
    from hilrig.apps.pdo_profile import apply_pdo_profile

    table = load_table(args)
    try:
        profile = table.board.pdo_profile(args.profile)
    except UnknownNameError as error:
        raise UsageError(str(error)) from None
    with open_bus(args) as bus, board_node(args, bus, table, writes=True) as node:
        progress(f"pdo: node 0x{node.node_id:02X} to pre-operational, writing PDO profile {profile.name}")
        try:
            apply_pdo_profile(node, profile)
        except SdoTimeoutError as error:
            raise NodeSilentError(f"{error}; {silent_hint(node.node_id)}") from error
        starts = {pdo.cob_id(node.node_id): pdo.sync_start for pdo in profile.tpdos if pdo.sync_start}
        for pdo in (*node.rpdos.values(), *node.tpdos.values()):  # as the node reads back
            if pdo.enabled and pdo.names:
                when = transmission_text(pdo.transmission_type)
                start = starts.get(pdo.cob_id) if pdo in node.tpdos.values() else None
                when += f" from SYNC counter {start}" if start else ""
                print(f"{pdo.label}: {when}: {', '.join(pdo.names)}")
        progress(f"pdo: profile {profile.name} stored (0x1010:02); the node stays pre-operational")
    return 0


COMMANDS = (
    Command(
        name="pdo",
        help="write one of the table's PDO profiles ([[pdo_profile]]) to a board and store it",
        description=(__doc__ or "").strip() + "\n\n"
        "The node is put pre-operational (remapping is refused in operational) and left there;\n"
        "each PDO is written in CiA 301's order, then 0x1019 (the SYNC counter the profile's\n"
        "start values count on) and 'store communication parameters' (0x1010:02).\n"
        "`hilrig bus-load --profile NAME` says what a profile puts on the bus. A board that is\n"
        "not the table's (0x1018 vendor id and product code) is refused first (--force: not).\n\n"
        "  hilrig pdo apply lean -c can0      # fits 1 Mbit/s at 1 kHz\n"
        "  hilrig pdo apply full -c can0      # back to everything every SYNC",
        configure=configure,
        run=run,
    ),
)
