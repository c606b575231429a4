"""`hilrig dbc`: the DBC of the board's default PDO frames for any node id; no bus needed."""

from __future__ import annotations

import argparse
import sys

from boardproto import TableError, load_table
from hilrig.cli.common import Command, UsageError, add_table_option, node_id, progress
from hilrig.cli.files import output_file


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "-n",
        "--node-id",
        type=node_id,
        default=None,
        help="CANopen node id the COB-IDs are for, 1..127, decimal or 0x hex (default: the table's, 0x10)",
    )
    parser.add_argument(
        "-o",
        "--output",
        type=output_file("DBC"),
        default=None,
        metavar="FILE",
        help="write the DBC to FILE (whole or not at all) instead of to stdout",
    )
    add_table_option(parser)


def run(args: argparse.Namespace) -> int:
    from boardproto.dbc import dbc_pdos, generate_dbc, node_id_warning  # cantools: a slow import
    from boardproto.outputs import write_if_changed

    try:
        table = load_table(args.table)
    except TableError as error:
        raise UsageError(str(error)) from None
    node = args.node_id if args.node_id is not None else table.node.default_node_id
    warning = node_id_warning(table, node)
    if warning is not None:
        print(f"{args.parser.prog}: warning: {warning}", file=sys.stderr)
    text = generate_dbc(table, node)
    if args.output is None:
        sys.stdout.write(text)
        return 0
    write_if_changed(args.output, text)  # a temporary file renamed over FILE
    progress(
        f"{args.parser.prog}: wrote {args.output}: {len(dbc_pdos(table))} PDO frames of node 0x{node:02X}"
    )
    return 0


COMMANDS = (
    Command(
        name="dbc",
        help="write the DBC of the PDO frames for a node id (SavvyCAN, cabana, cantools)",
        description="Write a DBC of the board's default PDO frames, generated from protocol/board.toml.\n"
        "A DBC tells bus tools which CAN identifier carries which fields, where in the frame,\n"
        "in which unit: SavvyCAN, cabana, PlotJuggler or `python -m cantools decode` then show\n"
        "motor_velocity in rad/s, control_mode as 'velocity' and fault_flags as the names of its\n"
        "bits, instead of raw bytes. A PDO's COB-ID is its base plus the node id, and a DBC holds\n"
        "fixed identifiers, so it fits one node id: build/protocol/board.dbc is for the default\n"
        "(0x10); this writes one for the node id your board has. Needs no bus.\n\n"
        "  hilrig dbc --node-id 0x20 -o board-32.dbc    # for a board at node 0x20\n"
        "  hilrig dbc -n 5 | less                       # to stdout\n"
        "  python -m cantools decode board-32.dbc < candump.log\n\n"
        "PDO 5..8 default to the COB-IDs of PDO 1..4 + 0x40, which are PDO 1..4's of node id + 64;\n"
        "so above 63 they are another node's PDO 1..4 identifiers, and a node id above 63 gets a\n"
        "warning when the table enables PDO 5..8 with their default COB-IDs.",
        configure=configure,
        run=run,
    ),
)
