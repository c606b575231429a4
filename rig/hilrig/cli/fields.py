"""`hilrig fields`: the board's fields and HIL I/O objects from the table; no bus needed."""

from __future__ import annotations

import argparse

from boardproto import Field, HilIo, IoDirection, Kind
from hilrig.cli.common import Command, UsageError, add_table_option, format_value, load_table, print_table

HIL_KINDS = ("hil_input", "hil_output")
KIND_CHOICES = (*(kind.value for kind in Kind), *HIL_KINDS)


def kind_of(entry: Field | HilIo) -> str:
    if isinstance(entry, Field):
        return entry.kind.value
    return "hil_input" if entry.direction is IoDirection.INPUT else "hil_output"


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "pattern",
        nargs="?",
        default="",
        metavar="SUBSTRING",
        help="only names containing this (e.g. velocity)",
    )
    parser.add_argument(
        "-k",
        "--kind",
        action="append",
        choices=KIND_CHOICES,
        metavar="KIND",
        help=f"only this kind (repeatable): {', '.join(KIND_CHOICES)}",
    )
    add_table_option(parser)


def run(args: argparse.Namespace) -> int:
    table = load_table(args)
    kinds = set(args.kind or KIND_CHOICES)
    entries = [e for e in table.board.entries if args.pattern in e.name and kind_of(e) in kinds]
    if not entries:
        raise UsageError(
            f"no field{' of kind ' + '/'.join(sorted(kinds)) if args.kind else ''} "
            f"contains {args.pattern!r}; `hilrig fields` alone lists them all"
        )
    rows = [
        [
            e.name,
            f"0x{e.index:04X}" + (f":{e.subindex}" if e.subindex else ""),  # an [[array]]'s member
            e.unit,
            kind_of(e),
            e.access.value,
            f"{format_value(e.min)}..{format_value(e.max)}",
            format_value(e.default) if isinstance(e, Field) else "-",
        ]
        for e in entries
    ]
    print_table(rows, ["name", "index", "unit", "kind", "access", "range", "default"])
    return 0


COMMANDS = (
    Command(
        name="fields",
        help="list the board fields (name, index, unit, kind, access, range, default)",
        description="List the board fields and HIL I/O objects of protocol/board.toml, the table the\n"
        "firmware, the EDS and the DBC are generated from. Needs no bus.\n\n"
        "  hilrig fields                    # everything\n"
        "  hilrig fields velocity           # names containing 'velocity'\n"
        "  hilrig fields --kind parameter   # what `hilrig set` can tune (stored)",
        configure=configure,
        run=run,
    ),
)
