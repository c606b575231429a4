"""`hilrig get NAME...` and `hilrig set NAME=VALUE...`: board fields over SDO, by name."""

from __future__ import annotations

import argparse
import math
import sys

from boardproto import Field, UnknownNameError
from boardproto.table import Access, BitSet, ValueEnum
from hilrig.cli.common import (
    Command,
    UsageError,
    add_node_options,
    assignment,
    board_node,
    check_names,
    field_name,
    format_unit,
    format_value,
    load_table,
    open_bus,
    print_table,
    resolved_node_id,
    silent_hint,
)
from hilrig.errors import SdoAbortError, SdoTimeoutError
from hilrig.table import ObjectEntry, RigTable


def parse_named(name: str, named: ValueEnum | BitSet, text: str) -> int | None:
    """The number a value name stands for ('velocity', 'motor_encoder_stale|thermistor_stale',
    'none'); None when `text` is no name (a number, say); a misspelt name is a usage error."""
    if not text[:1].isalpha():
        return None
    try:  # the table's own look-ups: a miss names the close matches
        if isinstance(named, ValueEnum):
            return named.value(text).value
        if text == "none":
            return 0
        return sum({named.bit(part.strip()).mask for part in text.split("|")})
    except UnknownNameError as error:
        raise UsageError(f"{name}: {error}") from None


def parse_assignment(
    text: str, entry_of: dict[str, ObjectEntry], table: RigTable | None = None
) -> tuple[str, float | int]:
    """'velocity_kp=0.2' -> ('velocity_kp', 0.2); HIL I/O objects take integers; a field whose
    values have names in board.toml also takes a name: 'control_mode=velocity' -> 1.0."""
    name, sep, value_text = text.partition("=")
    name, value_text = name.strip(), value_text.strip()
    if not sep or not name or not value_text:
        raise UsageError(f"expected NAME=VALUE, got {text!r} (e.g. velocity_kp=0.2)")
    entry = entry_of[name]
    named = table.board.values_of(name) if table is not None else None
    number = parse_named(name, named, value_text) if named is not None else None
    if number is not None:
        return name, float(number) if isinstance(entry, Field) else number
    if isinstance(entry, Field):
        try:
            value: float | int = float(value_text)
        except ValueError:
            raise UsageError(
                f"{name}: expected a number, got {value_text!r} (e.g. {name}={entry.default:g})"
            ) from None
        if not math.isfinite(value):
            raise UsageError(f"{name}: expected a finite number, got {value_text!r}")
        return name, value
    try:
        return name, int(value_text, 0)
    except ValueError:
        raise UsageError(
            f"{name} is a {entry.data_type.name} object: expected a whole number, got {value_text!r}"
        ) from None


def configure_get(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "names", type=field_name, nargs="+", metavar="NAME", help="field names (see `hilrig fields`)"
    )
    add_node_options(parser)


def configure_set(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "assignments",
        type=assignment,
        nargs="+",
        metavar="NAME=VALUE",
        help="e.g. velocity_kp=0.2; applied in order, stops at the first refusal",
    )
    add_node_options(parser, writes=True)


def run_get(args: argparse.Namespace) -> int:
    table = load_table(args)
    entries = check_names(table, args.names)
    rows: list[list[str]] = []
    failures: list[str] = []
    with open_bus(args) as bus, board_node(args, bus, table) as node:
        for entry in entries:
            try:
                value = node.read(entry.name)
            except SdoTimeoutError as error:
                raise SdoTimeoutError(f"{error}; {silent_hint(node.node_id)}") from error
            except SdoAbortError as error:
                failures.append(str(error))
                rows.append([entry.name, "=", "?", "(refused)"])
                continue
            named = table.board.values_of(entry.name)
            rows.append([entry.name, "=", format_value(value, named), format_unit(entry.unit)])
    print_table(rows)
    for failure in failures:
        print(f"hilrig get: error: {failure}", file=sys.stderr)
    return 1 if failures else 0


def run_set(args: argparse.Namespace) -> int:
    table = load_table(args)
    names = [text.partition("=")[0].strip() for text in args.assignments]
    entry_of = {entry.name: entry for entry in check_names(table, [n for n in names if n])}
    read_only = [name for name, entry in entry_of.items() if entry.access is Access.READ_ONLY]
    if read_only:  # refused here, nothing sent: the table says the node would refuse it
        raise UsageError(
            f'{", ".join(read_only)}: read-only over the bus (access = "ro" in board.toml); '
            "`hilrig fields --kind parameter` lists what can be set"
        )
    assignments = [parse_assignment(text, entry_of, table) for text in args.assignments]
    with open_bus(args) as bus, board_node(args, bus, table, writes=True) as node:
        for number, (name, value) in enumerate(assignments):
            try:
                node.write(name, value)
                actual = node.read(name)
            except SdoTimeoutError as error:
                raise SdoTimeoutError(f"{error}; {silent_hint(node.node_id)}") from error
            except SdoAbortError as error:
                skipped = [n for n, _ in assignments[number + 1 :]]
                rest = f"; not attempted: {', '.join(skipped)}" if skipped else ""
                print(
                    f"hilrig set: error: node 0x{resolved_node_id(args, table):02X} refused {error}{rest}",
                    file=sys.stderr,
                )
                return 1
            shown = format_value(actual, table.board.values_of(name))
            print_table([[name, "=", shown, format_unit(entry_of[name].unit)]])
            sys.stdout.flush()
    return 0


COMMANDS = (
    Command(
        name="get",
        help="read fields over SDO, printed with their units",
        description="Read board fields (or HIL I/O objects) from the node over SDO, by name.\n\n"
        "  hilrig get motor_velocity winding_temperature\n"
        "  hilrig get velocity_kp --interface pcan --channel PCAN_USBBUS1 --bitrate 500000\n\n"
        "A refusal prints the node's SDO abort code and what it means.",
        configure=configure_get,
        run=run_get,
    ),
    Command(
        name="set",
        help="write fields over SDO; refusals explained in words",
        description="Write board fields over SDO, in the order given, each read back and printed.\n"
        "The node judges the value: a refusal prints its SDO abort code in words\n"
        "(e.g. '0x06090031 value too high (max 10.0)') and stops there, exit code 1.\n"
        "First the node's 0x1018 identity is compared with the table's: another board is\n"
        "refused, nothing written, exit code 2 (--force writes anyway).\n\n"
        "  hilrig set control_mode=1 velocity_setpoint=2.5\n"
        "  hilrig set velocity_kp=0.2 velocity_ki=1.0",
        configure=configure_set,
        run=run_set,
    ),
)
