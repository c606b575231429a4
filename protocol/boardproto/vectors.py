"""`field_vectors.csv`: the parsed field table, one row per field, for cross-checks
(the C++ test compares every row with board::kFields)."""

from __future__ import annotations

import csv
import io

from boardproto.table import BoardTable

COLUMNS = ("name", "index", "unit", "kind", "access", "min", "max", "default", "stored")


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
