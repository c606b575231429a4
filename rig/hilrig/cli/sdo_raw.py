"""`hilrig sdo read INDEX[:SUB]` and `hilrig sdo write INDEX[:SUB] VALUE`: any object by index.

For bring-up, and for objects the table does not name (0x1017 heartbeat time, 0x1018
identity, a foreign device's 0x6041): canopen's SDO client with a raw index, the value
typed by --type or, for an object the EDS knows, by its type there.
"""

from __future__ import annotations

import argparse
import contextlib
import difflib
import math
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from hilrig import resources
from hilrig.cli.common import (
    EDS_HINT,
    Command,
    UsageError,
    add_node_options,
    add_verbose_option,
    check_board,
    load_eds,
    load_table,
    open_bus,
    resolved_node_id,
    silent_hint,
)
from hilrig.errors import RigError, SdoAbortError, SdoTimeoutError

if TYPE_CHECKING:
    from hilrig.session.canbus import Bus
    from hilrig.table import RigTable
    from hilrig.wire.node import BoardNode, ObjectDictionary

MAX_INDEX = 0xFFFF
MAX_SUBINDEX = 0xFF
Value = int | float | str | bytes


@dataclass(frozen=True)
class ValueType:
    """How a value travels in an SDO: a fixed-size little-endian number (`struct_format`), or
    text (UTF-8) or bytes of any length."""

    name: str  # as typed after --type: u16, f32, str
    struct_format: str | None = None  # '<H'; None: str or bytes

    @property
    def size(self) -> int | None:
        return struct.calcsize(self.struct_format) if self.struct_format else None

    @property
    def is_integer(self) -> bool:
        return self.struct_format is not None and self.struct_format[-1] not in "fd"

    def integer_range(self) -> tuple[int, int]:
        bits = 8 * (self.size or 0)
        signed = self.struct_format is not None and self.struct_format[-1].islower()
        return (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if signed else (0, (1 << bits) - 1)

    def encode(self, text: str, what: str) -> bytes:
        """The bytes of the value typed as `text`; a value that does not fit is a usage error."""
        if self.name == "str":
            return text.encode()
        if self.name == "bytes":
            digits = text.removeprefix("0x").removeprefix("0X").replace(" ", "").replace(":", "")
            try:
                return bytes.fromhex(digits)
            except ValueError:
                raise UsageError(f"{what} as bytes: expected hex like '01 02 0a', got {text!r}") from None
        assert self.struct_format is not None
        if self.is_integer:
            low, high = self.integer_range()
            try:
                number = int(text, 0)
            except ValueError:
                number = None
            if number is None or not low <= number <= high:
                raise UsageError(
                    f"{what} as {self.name}: expected a whole number {low}..{high} (decimal or 0x hex), "
                    f"got {text!r}"
                )
            return struct.pack(self.struct_format, number)
        try:
            real = float(text)
            return struct.pack(self.struct_format, real)
        except (ValueError, OverflowError):
            raise UsageError(f"{what} as {self.name}: expected a number that fits, got {text!r}") from None

    def decode(self, data: bytes) -> Value:
        if self.name == "str":
            return data.decode("utf-8", "replace").rstrip("\x00")
        if self.name == "bytes" or self.struct_format is None:
            return data
        return struct.unpack(self.struct_format, data)[0]

    def describe(self, data: bytes) -> str:
        """'567 (0x0237, u16)', '1.5 (0x3FC00000, f32)', "'joint' (6A 6F 69 6E 74, str)"."""
        if self.struct_format is None:
            raw = data.hex(" ").upper() or "no bytes"
            if self.name == "bytes":
                return f"{raw} ({len(data)} byte{'s' if len(data) != 1 else ''})"
            return f"{self.decode(data)!r} ({raw}, {self.name})"
        value = self.decode(data)
        shown = self._shortest(value, data) if isinstance(value, float) else str(value)
        return f"{shown} (0x{int.from_bytes(data, 'little'):0{2 * len(data)}X}, {self.name})"

    def _shortest(self, value: float, data: bytes) -> str:
        """The fewest digits that give back the same bytes: an f32 0.2 is '0.2', not 0.200000003."""
        assert self.struct_format is not None
        if not math.isfinite(value):
            return str(value)
        for digits in range(6, 18):
            text = f"{value:.{digits}g}"
            if struct.pack(self.struct_format, float(text)) == data:
                return text
        return repr(value)


VALUE_TYPES: dict[str, ValueType] = {
    t.name: t
    for t in (
        ValueType("u8", "<B"),
        ValueType("u16", "<H"),
        ValueType("u32", "<I"),
        ValueType("u64", "<Q"),
        ValueType("i8", "<b"),
        ValueType("i16", "<h"),
        ValueType("i32", "<i"),
        ValueType("i64", "<q"),
        ValueType("f32", "<f"),
        ValueType("f64", "<d"),
        ValueType("str"),
        ValueType("bytes"),
    )
}
_BY_SIZE = {1: "u8", 2: "u16", 4: "u32", 8: "u64"}


def _types_of_data_types() -> dict[int, ValueType]:
    """CiA 301 data type code (as canopen and board.toml's DataType number them) -> ValueType."""
    from hilrig.wire.sdo import value_type_names

    return {code: VALUE_TYPES[name] for code, name in value_type_names().items()}


# --- Argument types --------------------------------------------------------------------------
def object_address(text: str) -> tuple[int, int]:
    """'0x1018:1', '1018:1', '6041' -> (index, subindex): the index hex (0x optional, as CANopen
    writes it), the sub-index decimal or 0x hex, 0 when left out."""
    index_text, _, sub_text = text.partition(":")
    try:
        index = int(index_text, 16)
        subindex = int(sub_text, 16) if sub_text.lower().startswith("0x") else int(sub_text or "0", 10)
    except ValueError:
        index = -1
        subindex = 0
    if not (0 <= index <= MAX_INDEX and 0 <= subindex <= MAX_SUBINDEX):
        raise argparse.ArgumentTypeError(
            f"expected INDEX[:SUB], the index hex 0..FFFF (0x optional), the sub-index 0..255 "
            f"(e.g. 0x1018:1 or 6041), got {text!r}"
        )
    return index, subindex


def value_type(text: str) -> ValueType:
    try:
        return VALUE_TYPES[text.lower()]
    except KeyError:
        matches = difflib.get_close_matches(text.lower(), VALUE_TYPES, n=2, cutoff=0.5)
        hint = f"did you mean {' or '.join(matches)}? " if matches else ""
        raise argparse.ArgumentTypeError(
            f"unknown type {text!r}; {hint}types: {', '.join(VALUE_TYPES)}"
        ) from None


def _label(index: int, subindex: int) -> str:
    return f"0x{index:04X}:{subindex:02X}"


# --- The object and its type -----------------------------------------------------------------
@dataclass(frozen=True)
class ObjectInfo:
    """What the table and the EDS say about one object: its name and type, if they know it."""

    index: int
    subindex: int
    name: str | None
    value_type: ValueType | None

    @property
    def label(self) -> str:
        named = f" {self.name}" if self.name else ""
        return f"{_label(self.index, self.subindex)}{named}"


def object_info(index: int, subindex: int, table: RigTable, od: ObjectDictionary | None) -> ObjectInfo:
    """The table's name and type first (the one definition of the board's objects), then the
    EDS's (communication objects 0x1000.., and any device's EDS given with --eds)."""
    types = _types_of_data_types()
    entry = table.entry_at(index, subindex)
    if entry is not None:
        return ObjectInfo(index, subindex, entry.name, types.get(int(entry.data_type)))
    variable = od.get_variable(index, subindex) if od is not None else None
    if variable is not None:
        return ObjectInfo(index, subindex, variable.qualname, types.get(variable.data_type))
    return ObjectInfo(index, subindex, None, None)


def _od_for(args: argparse.Namespace, table: RigTable) -> tuple[ObjectDictionary | None, Path | None]:
    """The EDS of --eds, else the table's if there is one (build/protocol/board.eds in a checkout,
    once built): raw SDO works without one."""
    path: Path = args.eds if args.eds is not None else resources.eds_for(args.table)
    if not path.is_file():
        return None, None
    return load_eds(path, resolved_node_id(args, table)), path


def _unknown_type(info: ObjectInfo, eds: Path | None) -> str:
    built = f"no EDS ({resources.DEFAULT_EDS} is not built: {EDS_HINT})"
    where = f"not in {eds}" if eds is not None else built
    return f"{info.label}: its type is unknown ({where} nor in the table)"


@contextlib.contextmanager
def _node(
    args: argparse.Namespace,
    bus: Bus,
    table: RigTable,
    od: ObjectDictionary | None,
    *,
    writes: bool = False,
) -> Iterator[BoardNode]:
    from hilrig.wire.node import BoardNode

    node = BoardNode(bus, resolved_node_id(args, table), od, table, sdo_timeout_s=args.sdo_timeout)
    try:
        if writes:
            check_board(node, args)
        yield node
    finally:
        node.close()


def _refused(node_id: int, error: SdoAbortError) -> str:
    return f"node 0x{node_id:02X} refused {error}"


# --- read / write ----------------------------------------------------------------------------
def run_read(args: argparse.Namespace) -> int:
    table = load_table(args)
    od, _ = _od_for(args, table)
    info = object_info(*args.object, table, od)
    with open_bus(args) as bus, _node(args, bus, table, od) as node:
        try:
            data = node.upload(info.index, info.subindex, f"read {info.label}")
        except SdoTimeoutError as error:
            raise SdoTimeoutError(f"{error}; {silent_hint(node.node_id)}") from error
        except SdoAbortError as error:
            raise SdoAbortError(_refused(node.node_id, error), error.abort_code) from error
    print(f"{info.label} = {_describe_answer(args.type or info.value_type, data, info)}")
    return 0


def _describe_answer(kind: ValueType | None, data: bytes, info: ObjectInfo) -> str:
    """The value read, as `kind`; without one, by the answer's length (1, 2, 4, 8 bytes: an
    unsigned number) or as bytes."""
    if kind is None:
        by_size = _BY_SIZE.get(len(data))
        if by_size is None:
            return VALUE_TYPES["bytes"].describe(data)
        # "567 (0x0237, u16)" -> "567 (0x0237, u16 by its length)": a guess, and it says so
        return VALUE_TYPES[by_size].describe(data)[:-1] + " by its length)"
    size = kind.size
    if size is not None and len(data) != size:
        # An expedited answer that does not indicate its size carries 4 bytes, zero-padded.
        if len(data) == 4 and size < 4 and not any(data[size:]):
            data = data[:size]
        else:
            raise RigError(
                f"{info.label} answered {len(data)} bytes ({data.hex(' ').upper()}), not the {size} of "
                f"{kind.name}: read it with --type {_BY_SIZE.get(len(data), 'bytes')} or --type bytes"
            )
    return kind.describe(data)


def run_write(args: argparse.Namespace) -> int:
    table = load_table(args)
    od, eds = _od_for(args, table)
    info = object_info(*args.object, table, od)
    kind: ValueType | None = args.type or info.value_type
    if kind is None:
        raise UsageError(f"{_unknown_type(info, eds)}: give --type ({', '.join(VALUE_TYPES)})")
    data = kind.encode(args.value, info.label)
    with open_bus(args) as bus, _node(args, bus, table, od, writes=True) as node:
        try:
            node.download(info.index, info.subindex, data, f"write {info.label}")
        except SdoTimeoutError as error:
            raise SdoTimeoutError(f"{error}; {silent_hint(node.node_id)}") from error
        except SdoAbortError as error:
            raise SdoAbortError(_refused(node.node_id, error), error.abort_code) from error
    print(f"{info.label} := {kind.describe(data)}")
    return 0


# --- command line ----------------------------------------------------------------------------
def _add_object_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "object",
        type=object_address,
        metavar="INDEX[:SUB]",
        help="object index, hex (0x optional), and sub-index, decimal or 0x hex (default 0): "
        "0x1018:1, 6041, 0x1400:0x01",
    )
    parser.add_argument(
        "-t",
        "--type",
        type=value_type,
        default=None,
        help=f"the value's type: {', '.join(VALUE_TYPES)} (bytes in hex); default: the type "
        "board.toml or the EDS gives the object",
    )


def configure(parser: argparse.ArgumentParser) -> None:
    actions = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    read = actions.add_parser(
        "read",
        help="upload an object: its value and hex",
        description="Upload (read) one object by index over SDO; print its value and hex.\n\n"
        "  hilrig sdo read 0x1018:1             # vendor id\n"
        "  hilrig sdo read 1017                 # heartbeat producer time, u16 from the EDS\n"
        "  hilrig sdo read 0x6041 -t u16 -n 5   # a foreign device's status word",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    _add_object_arguments(read)
    add_node_options(read)
    add_verbose_option(read)
    read.set_defaults(parser=read)
    write = actions.add_parser(
        "write",
        help="download a value to an object",
        description="Download (write) one value to an object by index over SDO.\n\n"
        "  hilrig sdo write 0x1017 100                     # heartbeat every 100 ms\n"
        "  hilrig sdo write 0x2500 0.2                     # a board field, f32 from the table\n"
        "  hilrig sdo write 0x1010:1 -t u32 0x65766173     # 'save' (store parameters)\n"
        "  hilrig sdo write 0x3000 -t bytes '01 02'        # raw bytes, hex\n\n"
        "First the node's 0x1018 identity is compared with the table's: another device is\n"
        "refused, nothing written, exit code 2 (--force writes anyway: a foreign device).",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    _add_object_arguments(write)
    write.add_argument(
        "value", metavar="VALUE", help="the value: a number (decimal or 0x hex), text, or hex bytes"
    )
    add_node_options(write, writes=True)
    add_verbose_option(write)
    write.set_defaults(parser=write)


def run(args: argparse.Namespace) -> int:
    return run_read(args) if args.action == "read" else run_write(args)


COMMANDS = (
    Command(
        name="sdo",
        help="read or write any object by index over SDO (value and hex; aborts in words)",
        description=__doc__.split("\n\n", 1)[1].strip() + "\n\n"
        "  hilrig sdo read 0x1018:1\n"
        "  hilrig sdo write 0x1017 100\n"
        "  hilrig sdo read 0x6041 --type u16 --node-id 5\n\n"
        "A refusal prints the SDO abort code and what it means (exit code 1).",
        configure=configure,
        run=run,
    ),
)
