"""Cross-check vectors: the parsed table as CSV, written straight from `BoardTable`, so the C++
tests compare the generated header with what Python read (protocol/tests/FieldTableTest.cpp).

`field_vectors.csv`: one row per board field (board::kFields).
`value_vectors.csv`: one row per [[enum]] value, [[bitset]] bit and [[emcy]] code.

`python -m boardproto.vectors --table board.toml --out-dir DIR` writes value_vectors.csv.
"""

from __future__ import annotations

import argparse
import csv
import io
import sys
from collections.abc import Sequence
from pathlib import Path

from boardproto.table import BoardTable

COLUMNS = ("name", "index", "unit", "kind", "access", "min", "max", "default", "stored")

# kind:   enum | bit | emcy | recorder
# set:    the [[enum]] or [[bitset]] (empty for emcy and recorder)
# number: the enum value, the bit number, the EMCY code (0xXXXX), or the [recorder] setting
#         named (index 0xXXXX, channels, buffer_values, default_samples)
# emcy:   a bit's EMCY (empty: none); register_bit: an EMCY's error register bit (0xXX)
# about:  the object index a bit's EMCY names (0xXXXX; empty: named by the raiser at run time)
VALUE_COLUMNS = ("kind", "set", "name", "number", "emcy", "register_bit", "about")
VALUE_VECTORS = "value_vectors.csv"


def generate_field_vectors(table: BoardTable) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(COLUMNS)
    for field in table.fields:
        writer.writerow(
            (
                field.name,
                f"0x{field.index:04X}",
                field.unit,
                field.kind.value,
                field.access.value,
                repr(field.min),
                repr(field.max),
                repr(field.default),
                "1" if field.stored else "0",
            )
        )
    return buffer.getvalue()


def generate_value_vectors(table: BoardTable) -> str:
    """Enum values, flag bits and EMCY codes in table order; no descriptions."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(VALUE_COLUMNS)
    for values in table.enums:
        for value in values.values:
            writer.writerow(("enum", values.name, value.name, value.value, "", "", ""))
    for bitset in table.bitsets:
        for bit in bitset.bits:
            about = "" if bit.about is None else f"0x{table.entry(bit.about).index:04X}"
            writer.writerow(("bit", bitset.name, bit.name, bit.bit, bit.emcy or "", "", about))
    for code in table.emcy_codes:
        writer.writerow(
            ("emcy", "", code.name, f"0x{code.code:04X}", "", f"0x{code.error_register.value:02X}", "")
        )
    if table.recorder is not None:
        recorder = table.recorder
        for name, number in (
            ("index", f"0x{recorder.index:04X}"),
            ("channels", recorder.max_channels),
            ("buffer_values", recorder.buffer_values),
            ("default_samples", recorder.default_samples),
        ):
            writer.writerow(("recorder", "", name, number, "", "", ""))
    return buffer.getvalue()


def main(argv: Sequence[str] | None = None) -> int:
    from boardproto.loader import TableError, load_table
    from boardproto.outputs import write_if_changed

    parser = argparse.ArgumentParser(
        prog="python -m boardproto.vectors",
        description=f"Write {VALUE_VECTORS} (enum values, flag bits, EMCY codes) under OUT_DIR.",
    )
    parser.add_argument("--table", type=Path, required=True, help="the field table, e.g. protocol/board.toml")
    parser.add_argument("--out-dir", type=Path, required=True, help="output directory, e.g. build/protocol")
    arguments = parser.parse_args(argv)
    try:
        table = load_table(arguments.table)
    except TableError as error:
        print(f"boardproto: error: {error}", file=sys.stderr)
        return 2
    write_if_changed(arguments.out_dir / VALUE_VECTORS, generate_value_vectors(table))
    return 0


if __name__ == "__main__":
    sys.exit(main())
