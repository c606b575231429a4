"""board.toml's [[array]]s: CiA 301 ARRAY objects whose members are board fields.

An [[array]] names the object at its index (`name`, `index`, `description`); each member is an
ordinary [[field]] at that index with `subindex = n`. The members are fields like every other
(kind, range, default, stored, SDO and PDO access by name); the array adds sub 0, the number of
members (UNSIGNED8, read-only), and the rule that the members are sub 1..n of one data type.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from boardproto.loader import TableError, _check_name, _Entry, _entry_label, _unique_names
from boardproto.table import Field, FieldArray, ObjectEntry

_ARRAY_KEYS = frozenset({"name", "index", "description"})


def load_arrays(
    source: Path, documents: Sequence[Any], entries: Sequence[ObjectEntry]
) -> tuple[FieldArray, ...]:
    """The [[array]]s, checked against the fields and HIL I/O objects already loaded."""
    arrays: list[FieldArray] = []
    names = {e.name for e in entries}
    for position, data in enumerate(documents):
        entry = _Entry(source, _entry_label("array", position, data), data)
        entry.check_keys(_ARRAY_KEYS)
        name = _check_name(entry)
        if name in names:
            raise entry.error(f"name {name!r} is already a field's or HIL I/O object's")
        index = entry.integer("index", 0, 0xFFFF)
        at_index = [e for e in entries if e.index == index]
        plain = next((e for e in at_index if e.subindex == 0), None)
        if plain is not None:
            raise entry.error(f"index 0x{index:04X} is taken by {plain.name!r}, a plain object (sub-index 0)")
        members = sorted((e for e in at_index if isinstance(e, Field)), key=lambda f: f.subindex)
        if not members:
            raise entry.error(f"no [[field]] at index 0x{index:04X} with subindex = 1.. is a member")
        subs = [m.subindex for m in members]
        if subs != list(range(1, len(members) + 1)):
            raise entry.error(f"members must be sub-indices 1..{len(members)}, got {subs}")
        types = {m.data_type for m in members}
        if len(types) > 1:
            raise entry.error(
                "members of an ARRAY share one type, got "
                + ", ".join(f"{m.name} {m.data_type.toml_name}" for m in members)
            )
        arrays.append(FieldArray(name, index, entry.text("description"), tuple(m.name for m in members)))
    _unique_names(source, "array", arrays)
    indices = {a.index for a in arrays}
    for other in entries:
        if other.subindex and other.index not in indices:
            raise TableError(
                f"{source}: field {other.name!r}: subindex {other.subindex} needs an [[array]] "
                f"at index 0x{other.index:04X}"
            )
    seen: set[int] = set()
    for array in arrays:
        if array.index in seen:
            raise TableError(f"{source}: array {array.name!r}: index 0x{array.index:04X} declared twice")
        seen.add(array.index)
    return tuple(sorted(arrays, key=lambda a: a.index))
