"""The rig's view of the board table: names checked against protocol/board.toml, nothing copied.

Everything comes from `boardproto.load_table`, so a field added to board.toml is known to the
rig at once. A name the table does not define raises `FieldNameError` with the close matches::

    table = RigTable.load()
    table.entry("motor_velocty")   # FieldNameError: no board field or HIL I/O object named
                                   # 'motor_velocty'; did you mean 'motor_velocity'?
"""

from __future__ import annotations

import enum
import tomllib
from collections.abc import Iterable
from pathlib import Path

from boardproto import BoardTable, Field, HilIo, Kind, TableError, load_table, parse_table
from hilrig import resources
from hilrig.errors import FieldNameError, unknown_name

DEFAULT_TABLE_PATH = resources.DEFAULT_TABLE
"""protocol/board.toml of the checkout this package lives in, or the wheel's copy of it."""

BOARD_TABLE = load_table(DEFAULT_TABLE_PATH)
"""The table the firmware of this checkout (or of this wheel's build) is built from."""

# The named values that travel in fields, built from board.toml at import: moving a fault bit or
# adding a control mode there changes these with no other edit. Members are the table's names in
# upper case (ControlMode.VELOCITY, FaultFlags.MOTOR_ENCODER_STALE, EmcyCode.STALE_SENSOR).
ControlMode = BOARD_TABLE.enum("control_mode").python_type()
LedPattern = BOARD_TABLE.enum("led_pattern").python_type()
FaultFlags = BOARD_TABLE.bitset("fault_flags").python_type()
EmcyCode = enum.IntEnum("EmcyCode", {code.name.upper(): code.code for code in BOARD_TABLE.emcy_codes})

ObjectEntry = Field | HilIo


class RigTable:
    """Name look-ups over a `BoardTable`; every miss raises FieldNameError with suggestions."""

    def __init__(self, board: BoardTable) -> None:
        self.board = board
        self._entries: dict[str, ObjectEntry] = {entry.name: entry for entry in board.entries}
        self._by_index: dict[tuple[int, int], ObjectEntry] = {
            (entry.index, entry.subindex): entry for entry in board.entries
        }

    @classmethod
    def load(cls, path: str | Path = DEFAULT_TABLE_PATH) -> RigTable:
        # The default table is parsed once, at import (BOARD_TABLE); others on each call.
        return cls(BOARD_TABLE if resources.is_default_table(Path(path)) else load_table(path))

    @classmethod
    def loads(cls, text: str, name: str = "board.toml") -> RigTable:
        """A table from its TOML text (the copy a trace records); `name` says where it came from in
        errors (TableError)."""
        try:
            return cls(parse_table(Path(name), tomllib.loads(text)))
        except tomllib.TOMLDecodeError as error:
            raise TableError(f"{name}: not valid TOML: {error}") from None

    @property
    def is_default_board(self) -> bool:
        """The demo board's table (its vendor and product code), wherever it was read from."""
        node, default = self.board.node, BOARD_TABLE.node
        return (node.vendor_id, node.product_code) == (default.vendor_id, default.product_code)

    @property
    def names(self) -> tuple[str, ...]:
        """Board fields, then HIL inputs, then HIL outputs."""
        return tuple(self._entries)

    def entry(self, name: str) -> ObjectEntry:
        """A board field or HIL I/O object by name."""
        try:
            return self._entries[name]
        except KeyError:
            raise unknown_name("board field or HIL I/O object", name, self._entries) from None

    def field(self, name: str) -> Field:
        entry = self.entry(name)
        if not isinstance(entry, Field):
            raise FieldNameError(f"{name!r} is a HIL I/O object, not a board field")
        return entry

    def entry_at(self, index: int, subindex: int = 0) -> ObjectEntry | None:
        """The field or HIL I/O object at (index, subindex): an [[array]]'s members at 1..n."""
        return self._by_index.get((index, subindex))

    def check(self, names: Iterable[str]) -> None:
        """Raise FieldNameError for the first unknown name (scenarios call this at start)."""
        for name in names:
            self.entry(name)

    def is_hil_input(self, name: str) -> bool:
        return any(io.name == name for io in self.board.hil_inputs)

    def is_bus_writable(self, name: str) -> bool:
        entry = self.entry(name)
        return (isinstance(entry, Field) and entry.kind.bus_writable) or (
            isinstance(entry, HilIo) and self.is_hil_input(name)
        )

    @property
    def setpoint_stream(self) -> tuple[str, ...]:
        """The fields a master sends every cycle (the table's `stream = true`)."""
        return self.board.setpoint_stream

    def fields_of_kind(self, kind: Kind) -> tuple[Field, ...]:
        return self.board.fields_of_kind(kind)


__all__ = [
    "BOARD_TABLE",
    "DEFAULT_TABLE_PATH",
    "ControlMode",
    "EmcyCode",
    "FaultFlags",
    "LedPattern",
    "ObjectEntry",
    "RigTable",
    "unknown_name",
]
