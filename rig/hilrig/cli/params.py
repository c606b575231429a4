"""`hilrig params save|load FILE.dcf`: a board's parameter set as a DCF (CiA 306).

`save` reads every object the board stores (its 0x1010 set: the stored communication objects,
PDOs included, and the board fields the table marks `stored`) over SDO and writes them, with
their values, as a DCF (the board's EDS with a ParameterValue each; COB-IDs that follow the node
id stay written relative to it). `load` writes a DCF's values to a board (PDOs in CiA 301's
order; the board must be pre-operational), stores them with 0x1010 (--no-store: not), and reads
every one back. A DCF of another product, or a board that is not the table's (0x1018 vendor id
and product code; --force: written anyway), is refused before anything is written.
"""

from __future__ import annotations

import argparse

from hilrig.cli.common import (
    Command,
    add_node_options,
    board_node,
    describe_bus,
    existing_file,
    load_table,
    open_bus,
    progress,
    resolved_node_id,
)
from hilrig.cli.files import output_file

DCF_SUFFIXES = (".dcf", ".eds")
"""What a parameter set is read from and written as (a DCF is an EDS with values)."""


def configure(parser: argparse.ArgumentParser) -> None:
    actions = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    save = actions.add_parser("save", help="write the board's stored objects and their values to a DCF")
    save.add_argument(
        "file",
        type=output_file("DCF", suffixes=DCF_SUFFIXES),
        metavar="FILE.dcf",
        help="the DCF to write (replaced whole)",
    )
    load = actions.add_parser("load", help="write a DCF's values to the board, store and verify them")
    load.add_argument(
        "file",
        type=existing_file("DCF", "`hilrig params save FILE.dcf` writes one", suffixes=DCF_SUFFIXES),
        metavar="FILE.dcf",
        help="the DCF to read",
    )
    load.add_argument("--no-store", action="store_true", help="write and verify, but do not store (0x1010)")
    add_node_options(save, sdo_timeout_s=1.0)
    add_node_options(load, sdo_timeout_s=1.0, writes=True)


def run(args: argparse.Namespace) -> int:
    from hilrig.cli.common import UsageError
    from hilrig.wire.dcf import DcfError, load_dcf, read_dcf, save_dcf, stored_objects

    table = load_table(args)
    node_id = resolved_node_id(args, table)
    if args.action == "load":
        try:
            dcf = read_dcf(args.file, node_id)
        except DcfError as error:
            raise UsageError(str(error)) from None
    with open_bus(args) as bus, board_node(args, bus, table, writes=args.action == "load") as node:
        if args.action == "save":
            count = len(stored_objects(node.remote.object_dictionary, table))
            on = f"node 0x{node_id:02X} on {describe_bus(args)}"
            progress(f"params: reading {count} stored objects of {on}")
            save_dcf(node.remote, table, args.file)
            print(f"{args.file}: {count} objects of node 0x{node_id:02X}")
            return 0
        progress(f"params: writing {args.file} to node 0x{node_id:02X} on {describe_bus(args)}")
        report = load_dcf(node.remote, dcf, table, store=not args.no_store)
    stored = "stored (0x1010)" if report.stored else "not stored"
    written = f"{report.written} objects written, {stored}"
    print(f"node 0x{node_id:02X}: {written}, {report.verified} read back equal")
    return 0


COMMANDS = (
    Command(
        name="params",
        help="save a board's stored parameters to a DCF, or load one into a board (stored, verified)",
        description=__doc__.split("\n\n", 1)[1].strip() + "\n\n"
        "  hilrig params save board.dcf            # the table's node (0x10)\n"
        "  hilrig params load board.dcf -n 0x11    # onto the next board, stored and read back\n",
        configure=configure,
        run=run,
    ),
)
