"""Load board.toml and validate it into a `BoardTable`.

Every problem raises `TableError` with a message of the form
"<file>: <what> '<name>': <problem>", so one line on stderr says where to look.
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar

from boardproto.cia301 import LAST_SYNCHRONOUS_TYPE, RPDO_FUNCTIONS, TPDO_FUNCTIONS, predefined_pdo_base
from boardproto.cpp_keywords import CPP_KEYWORDS
from boardproto.standard import STANDARD_TRANSMISSION_TYPES, merge_standard, pdo_slots, standard_document
from boardproto.table import (
    HIL_IO_TYPES,
    RECORDER_ENUMS,
    Access,
    BitSet,
    BoardTable,
    DataType,
    EmcyCode,
    EnumValue,
    ErrorRegisterBit,
    Field,
    FlagBit,
    HilIo,
    IoDirection,
    Kind,
    NodeIdentity,
    ObjectEntry,
    Pdo,
    PdoDirection,
    PdoEntry,
    Recorder,
    RecorderObject,
    ValueEnum,
    unknown_name_message,
)

_Choice = TypeVar("_Choice", Kind, Access)


class TableError(ValueError):
    """board.toml is malformed or inconsistent; the message names file, entry and problem."""


MANUFACTURER_RANGE = range(0x2000, 0x6000)
# Standardised device profile area (CiA 301, 7.4.1): a board field of a device profile (CiA 402's
# objects of the first logical device) lives here, with the integer type the profile gives it.
PROFILE_RANGE = range(0x6000, 0xA000)
# A typed field's values are held in a float on the board: integers up to 2**24 are exact there.
FLOAT_EXACT_INTEGER = 1 << 24
MAX_PDO_BITS = 64  # classic CAN: 8 data bytes
MAX_PDO_ENTRIES = 8
MAX_PDO_SLOTS = 512  # CiA 301: 0x1400..0x15FF, 0x1800..0x19FF
MAX_NODE_ID = 127
FLOAT32_MAX = 3.4028234663852886e38

# An Actuator reads the board and drives hardware; it writes no field, and the bus writes only rw
# (command, parameter) fields: a field of kind actuator would have no writer at all.
ACTUATOR_FIELD_FIX = (
    "kind 'actuator' has no writer (an Actuator only reads the board and drives hardware): make what "
    "it drives a [[hil_output]] (the raw value the plant takes) and the value it executes a module "
    "field (what a controller computes) or a command field (what the bus sets)"
)
_SNAKE_CASE = re.compile(r"[a-z][a-z0-9]*(?:_[a-z0-9]+)*")
# Printable ASCII without space, comma or quotes: units go into C++ strings, CSV and DBC.
_UNIT = re.compile(r"[!#-&(-+\--~]+")
# Transmission types CiA 301 defines for both directions (241..251 are reserved,
# 252/253 are RTR-only TPDO types the firmware does not implement).
_TRANSMISSION_TYPES = frozenset((*range(0, 241), 254, 255))

_TOP_LEVEL_KEYS = frozenset(
    {
        "node",
        "emcy",
        "field",
        "enum",
        "bitset",
        "hil_input",
        "hil_output",
        "pdo",
        "rpdo",
        "tpdo",
        "pdo_profile",
        "recorder",
        "array",
    }
)
# The board's identity: no default (boardproto.standard has the other [node] keys').
_NODE_IDENTITY_KEYS = frozenset(
    {
        "vendor_id",
        "product_code",
        "revision",
        "device_name",
        "hardware_version",
        "software_version",
        "default_node_id",
    }
)
_NODE_STANDARD_KEYS = frozenset(standard_document()["node"])
_FIELD_KEYS = frozenset({"name", "index", "unit", "kind", "min", "max", "description"})
# Optional on a field: access follows from its kind (the only one the loader accepts), a field is
# not stored and starts at 0 (or its min, when 0 is outside its range) unless it says otherwise;
# `stream = true` puts a command field in the setpoint stream a master sends every cycle.
# `subindex` n (1..) makes the field the n-th member of the [[array]] at its index; 0 is plain.
_FIELD_OPTIONAL_KEYS = frozenset({"access", "default", "stored", "stream", "type", "subindex"})
_HIL_IO_KEYS = frozenset({"name", "index", "type", "min", "max", "unit", "description"})
_VALUES_KEY = frozenset({"values"})  # optional on fields and HIL I/O: the enum or bitset carried
_NAMED_SET_KEYS = frozenset({"name", "description"})
_ENUM_VALUE_KEYS = frozenset({"name", "value", "description"})
_BIT_REQUIRED_KEYS = frozenset({"name", "bit", "description"})
_BIT_OPTIONAL_KEYS = frozenset({"emcy", "about"})
_EMCY_KEYS = frozenset({"name", "code", "error_register", "description"})
# 0x1016 consumer heartbeat time entries: each is fixed RAM in the node and a stored value; a
# module of a chain watches the master and its two neighbours, plus a spare.
MAX_HEARTBEAT_CONSUMERS = 4
MAX_FLAG_BITS = 24  # a bitset travels in a REAL32 field: integers are exact up to 2**24
_PDO_SLOT_KEYS = frozenset({"rpdo_slots", "tpdo_slots"})
_RECORDER_KEYS = frozenset({"index", "channels", "buffer_values"})
# Sub-indices 1..n of the channel array (UNSIGNED8 sub-index, the DOMAIN's UNSIGNED8 count).
MAX_RECORDER_CHANNELS = 254
MAX_ARRAY_MEMBERS = 254  # an [[array]]'s sub-indices 1..n (UNSIGNED8 sub 0)
# The sample memory's REAL32 values: 16 MiB at most, so sizes and offsets stay far inside 32 bits.
MAX_RECORDER_VALUES = 1 << 22
# Recorder objects carry enum values in UNSIGNED8 objects.
_RECORDER_ENUM_RANGE = range(0, 0x100)  # protocol-literal: the UNSIGNED8 range
_PDO_REQUIRED_KEYS = frozenset({"number", "map"})
_PDO_OPTIONAL_KEYS = frozenset(
    {"transmission_type", "enabled", "inhibit_time_100us", "event_timer_ms", "cob_id_base", "sync_start"}
)


class _Entry:
    """One table of board.toml being read, with error messages that say which one."""

    def __init__(self, source: Path, what: str, data: Any) -> None:
        self.source = source
        self.what = what
        if not isinstance(data, Mapping):
            raise self.error(f"expected a table, got {type(data).__name__}")
        self.data: Mapping[str, Any] = data

    def error(self, problem: str) -> TableError:
        return TableError(f"{self.source}: {self.what}: {problem}")

    def check_keys(self, required: frozenset[str], optional: frozenset[str] = frozenset()) -> None:
        allowed = required | optional
        for key in self.data:
            if key not in allowed:
                raise self.error(
                    unknown_name_message("key", key, sorted(allowed)).replace("no key named", "unknown key")
                )
        missing = sorted(required - self.data.keys())
        if missing:
            raise self.error(f"missing key{'s' if len(missing) > 1 else ''} {', '.join(missing)}")

    def integer(self, key: str, low: int, high: int, default: int | None = None) -> int:
        value = self.data.get(key, default)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(f"{key} must be an integer, got {value!r}")
        if not low <= value <= high:
            raise self.error(f"{key} {_hex_or_int(value)} outside {_hex_or_int(low)}..{_hex_or_int(high)}")
        return value

    def real(self, key: str) -> float:
        value = self.data[key]
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.error(f"{key} must be a number, got {value!r}")
        value = float(value)
        if not math.isfinite(value) or abs(value) > FLOAT32_MAX:
            raise self.error(f"{key} {value!r} is not a finite 32-bit float")
        return value

    def boolean(self, key: str, default: bool | None = None) -> bool:
        value = self.data.get(key, default)
        if not isinstance(value, bool):
            raise self.error(f"{key} must be true or false, got {value!r}")
        return value

    def text(self, key: str, *, allow_empty: bool = False) -> str:
        value = self.data[key]
        if not isinstance(value, str):
            raise self.error(f"{key} must be a string, got {value!r}")
        if not allow_empty and not value:
            raise self.error(f"{key} must not be empty")
        if not all(" " <= ch <= "~" for ch in value):
            raise self.error(f"{key} must be one line of printable ASCII, got {value!r}")
        return value

    def optional_text(self, key: str) -> str | None:
        return self.text(key) if key in self.data else None

    def unit(self) -> str:
        value = self.text("unit")
        if not _UNIT.fullmatch(value):
            raise self.error(f"unit {value!r} must not contain spaces, commas or quotes")
        return value

    def choice(self, key: str, enum_type: type[_Choice]) -> _Choice:
        value = self.text(key)
        try:
            return enum_type(value)
        except ValueError:
            allowed = ", ".join(member.value for member in enum_type)
            raise self.error(f"unknown {key} {value!r} (one of: {allowed})") from None


def _hex_or_int(value: int) -> str:
    return f"0x{value:X}" if value >= 0x100 else str(value)  # protocol-literal: hex from 3 digits


def _check_name(entry: _Entry) -> str:
    name = entry.text("name")
    if not _SNAKE_CASE.fullmatch(name):
        raise entry.error(f"name {name!r} is not snake_case (lower-case words joined by _)")
    if name in CPP_KEYWORDS:
        raise entry.error(f"name {name!r} is a C++ keyword")
    return name


def _entry_label(kind: str, position: int, data: Any) -> str:
    name = data.get("name") if isinstance(data, Mapping) else None
    return f"{kind} {name!r}" if isinstance(name, str) else f"{kind} #{position + 1}"


def _array_of_tables(source: Path, document: Mapping[str, Any], key: str) -> list[Any]:
    value = document.get(key, [])
    if not isinstance(value, list):
        raise TableError(f"{source}: {key} must be an array of tables ([[{key}]])")
    return value


def _load_node(source: Path, data: Any) -> NodeIdentity:
    entry = _Entry(source, "node", data)
    entry.check_keys(_NODE_IDENTITY_KEYS, _NODE_STANDARD_KEYS)
    u32 = 0xFFFF_FFFF
    # The firmware's period is an UNSIGNED32 of microseconds: the range's ends bound the default.
    period_min = entry.integer("period_us_min", 1, u32)
    period_max = entry.integer("period_us_max", period_min, u32)
    period_us = entry.integer("period_us", period_min, period_max)
    return NodeIdentity(
        device_type=entry.integer("device_type", 0, u32),
        vendor_id=entry.integer("vendor_id", 0, u32),
        product_code=entry.integer("product_code", 0, u32),
        revision=entry.integer("revision", 0, u32),
        device_name=entry.text("device_name"),
        hardware_version=entry.text("hardware_version"),
        software_version=entry.text("software_version"),
        default_node_id=entry.integer("default_node_id", 1, MAX_NODE_ID),
        heartbeat_ms=entry.integer("heartbeat_ms", 0, 0xFFFF),
        # 0x1003 sub 0 is an UNSIGNED8 count; 254 is the largest useful sub-index.
        error_history_length=entry.integer("error_history_length", 1, 254),
        heartbeat_consumers=entry.integer("heartbeat_consumers", 1, MAX_HEARTBEAT_CONSUMERS),
        bitrate=entry.integer("bitrate", 10_000, 1_000_000),  # classic CAN: 10 kbit/s .. 1 Mbit/s
        mcu_clock_hz=entry.integer("mcu_clock_hz", 1_000_000, 0xFFFF_FFFF),
        cycle_budget_percent=entry.integer("cycle_budget_percent", 1, 100),
        period_us=period_us,
        period_us_min=period_min,
        period_us_max=period_max,
        boot_ms=entry.integer("boot_ms", 0, 60_000),
    )


def _load_field(source: Path, position: int, data: Any) -> Field:
    entry = _Entry(source, _entry_label("field", position, data), data)
    entry.check_keys(_FIELD_KEYS, _VALUES_KEY | _FIELD_OPTIONAL_KEYS)
    name = _check_name(entry)
    index = entry.integer("index", 0, 0xFFFF)
    kind = entry.choice("kind", Kind)
    if kind is Kind.ACTUATOR:
        raise entry.error(ACTUATOR_FIELD_FIX)
    # Bus-written fields are owned by the CANopen node; a second writer would be a
    # start-up error in the firmware, so refuse the table instead.
    expected_access = Access.READ_WRITE if kind.bus_writable else Access.READ_ONLY
    access = entry.choice("access", Access) if "access" in entry.data else expected_access
    data_type = _field_type(entry, index)
    if data_type is DataType.REAL32:
        low, high = entry.real("min"), entry.real("max")
    else:
        type_low, type_high = data_type.integer_range
        type_low, type_high = max(type_low, -FLOAT_EXACT_INTEGER), min(type_high, FLOAT_EXACT_INTEGER)
        low = float(entry.integer("min", type_low, type_high))
        high = float(entry.integer("max", type_low, type_high))
    if low > high:
        raise entry.error(f"min {low!r} is greater than max {high!r}")
    if "default" not in entry.data:
        default = min(max(0.0, low), high)
    elif data_type is DataType.REAL32:
        default = entry.real("default")
    else:
        default = float(entry.integer("default", int(low), int(high)))
    stored = entry.boolean("stored", False)
    if not low <= default <= high:
        raise entry.error(f"default {default!r} outside [{low!r}, {high!r}]")
    if access is not expected_access:
        raise entry.error(
            f"a {kind.value} field must have access {expected_access.value!r}, got {access.value!r}"
        )
    if stored and access is not Access.READ_WRITE:
        raise entry.error("only rw fields can be stored (a ro field is recomputed by firmware)")
    stream = entry.boolean("stream", False)
    if stream and kind is not Kind.COMMAND:
        raise entry.error(f"only command fields are streamed (a master sends them), not a {kind.value} field")
    return Field(
        name=name,
        index=index,
        unit=entry.unit(),
        kind=kind,
        access=access,
        min=low,
        max=high,
        default=default,
        stored=stored,
        description=entry.text("description"),
        values=entry.optional_text("values"),
        stream=stream,
        data_type=data_type,
        subindex=entry.integer("subindex", 0, MAX_ARRAY_MEMBERS, default=0),
    )


def _field_type(entry: _Entry, index: int) -> DataType:
    """REAL32 in the manufacturer range; the integer type named by `type` in the profile range."""
    if index in PROFILE_RANGE:
        if "type" not in entry.data:
            raise entry.error(
                f"index 0x{index:04X} is a device profile object: give it the profile's type "
                f"(type = one of: {', '.join(t.toml_name for t in HIL_IO_TYPES)})"
            )
        types = {t.toml_name: t for t in HIL_IO_TYPES}
        type_name = entry.text("type")
        if type_name not in types:
            raise entry.error(f"unknown type {type_name!r} (one of: {', '.join(types)})")
        return types[type_name]
    if "type" in entry.data and entry.data["type"] != DataType.REAL32.toml_name:
        raise entry.error(
            "a field in the manufacturer range is a real32: only a device profile object "
            "(index 0x6000..0x9FFF) takes an integer type"
        )
    return DataType.REAL32


def _load_hil_io(source: Path, direction: IoDirection, position: int, data: Any) -> HilIo:
    entry = _Entry(source, _entry_label(f"hil_{direction.value}", position, data), data)
    entry.check_keys(_HIL_IO_KEYS, _VALUES_KEY)
    name = _check_name(entry)
    index = entry.integer("index", 0, 0xFFFF)
    type_name = entry.text("type")
    types = {t.toml_name: t for t in HIL_IO_TYPES}
    if type_name not in types:
        raise entry.error(f"unknown type {type_name!r} (one of: {', '.join(types)})")
    data_type = types[type_name]
    type_low, type_high = data_type.integer_range
    low = entry.integer("min", type_low, type_high)
    high = entry.integer("max", type_low, type_high)
    if low > high:
        raise entry.error(f"min {low} is greater than max {high}")
    return HilIo(
        name=name,
        index=index,
        data_type=data_type,
        min=low,
        max=high,
        unit=entry.unit(),
        description=entry.text("description"),
        direction=direction,
        values=entry.optional_text("values"),
    )


def _load_emcy(source: Path, position: int, data: Any) -> EmcyCode:
    entry = _Entry(source, _entry_label("emcy", position, data), data)
    entry.check_keys(_EMCY_KEYS)
    registers = {bit.toml_name: bit for bit in ErrorRegisterBit}
    register = entry.text("error_register")
    if register not in registers:
        raise entry.error(f"unknown error_register {register!r} (one of: {', '.join(registers)})")
    # 0x0000 is "error reset"; the firmware sends it itself when an error clears.
    return EmcyCode(
        name=_check_name(entry),
        code=entry.integer("code", 0x0001, 0xFFFF),
        error_register=registers[register],
        description=entry.text("description"),
    )


def _nested(entry: _Entry, key: str) -> list[Any]:
    value = entry.data.get(key)
    if not isinstance(value, list) or not value:
        raise entry.error(f"defines no [[{entry.what.split()[0]}.{key}]]")
    return value


def _load_enum(source: Path, position: int, data: Any) -> ValueEnum:
    entry = _Entry(source, _entry_label("enum", position, data), data)
    entry.check_keys(_NAMED_SET_KEYS | {"values"})
    name = _check_name(entry)
    values: list[EnumValue] = []
    for n, item in enumerate(_nested(entry, "values")):
        value_entry = _Entry(source, f"{entry.what}: {_entry_label('value', n, item)}", item)
        value_entry.check_keys(_ENUM_VALUE_KEYS)
        value = EnumValue(
            name=_check_name(value_entry),
            # exact in the REAL32 field that carries it
            value=value_entry.integer("value", -(1 << 24), 1 << 24),
            description=value_entry.text("description"),
        )
        for other in values:
            if other.name == value.name:
                raise value_entry.error("duplicate name")
            if other.value == value.value:
                raise value_entry.error(f"value {value.value} already used by {other.name!r}")
        values.append(value)
    return ValueEnum(name=name, description=entry.text("description"), values=tuple(values))


def _load_bitset(
    source: Path, position: int, data: Any, emcy: Mapping[str, EmcyCode], objects: Mapping[str, ObjectEntry]
) -> BitSet:
    entry = _Entry(source, _entry_label("bitset", position, data), data)
    entry.check_keys(_NAMED_SET_KEYS | {"bits"})
    name = _check_name(entry)
    bits: list[FlagBit] = []
    for n, item in enumerate(_nested(entry, "bits")):
        bit_entry = _Entry(source, f"{entry.what}: {_entry_label('bit', n, item)}", item)
        bit_entry.check_keys(_BIT_REQUIRED_KEYS, _BIT_OPTIONAL_KEYS)
        bit = FlagBit(
            name=_check_name(bit_entry),
            bit=bit_entry.integer("bit", 0, MAX_FLAG_BITS - 1),
            description=bit_entry.text("description"),
            emcy=bit_entry.optional_text("emcy"),
            about=bit_entry.optional_text("about"),
        )
        if bit.emcy is not None and bit.emcy not in emcy:
            raise bit_entry.error(unknown_name_message("[[emcy]]", bit.emcy, emcy))
        if bit.about is not None:
            if bit.emcy is None:
                raise bit_entry.error("about names the object of an EMCY: set emcy too")
            if bit.about not in objects:
                raise bit_entry.error(unknown_name_message("board object", bit.about, objects))
        for other in bits:
            if other.name == bit.name:
                raise bit_entry.error("duplicate name")
            if other.bit == bit.bit:
                raise bit_entry.error(f"bit {bit.bit} already used by {other.name!r}")
        bits.append(bit)
    return BitSet(name=name, description=entry.text("description"), bits=tuple(bits))


def _check_values(
    source: Path, entries: list[ObjectEntry], enums: list[ValueEnum], bitsets: list[BitSet]
) -> None:
    """Every `values = "x"` names an enum or bitset, and the carrier's range holds its values."""
    sets: dict[str, ValueEnum | BitSet] = {}
    for named in (*enums, *bitsets):
        if named.name in sets:
            raise TableError(f"{source}: {named.name!r}: an enum and a bitset cannot share a name")
        sets[named.name] = named
    for entry in entries:
        if entry.values is None:
            continue
        what = "field" if isinstance(entry, Field) else f"hil_{entry.direction.value}"
        where = f"{source}: {what} {entry.name!r}"
        if entry.values not in sets:
            raise TableError(f"{where}: values: {unknown_name_message('enum or bitset', entry.values, sets)}")
        named = sets[entry.values]
        numbers = (
            [v.value for v in named.values]
            if isinstance(named, ValueEnum)
            else [sum(b.mask for b in named.bits)]
        )
        outside = [n for n in numbers if not entry.min <= n <= entry.max]
        if outside:
            raise TableError(
                f"{where}: {named.name} value {outside[0]} outside its range [{entry.min}, {entry.max}]"
            )
        # The firmware starts with the default: it must mean something.
        if isinstance(entry, Field) and isinstance(named, ValueEnum) and named.name_of(entry.default) is None:
            choices = ", ".join(f"{v.name} {v.value}" for v in named.values)
            raise TableError(f"{where}: default {entry.default!r} is no {named.name} value ({choices})")


def _unique_names(source: Path, what: str, items: list[Any]) -> None:
    seen: set[str] = set()
    for item in items:
        if item.name in seen:
            raise TableError(f"{source}: {what} {item.name!r}: duplicate name")
        seen.add(item.name)


def _check_unique(source: Path, entries: list[ObjectEntry]) -> None:
    by_name: dict[str, ObjectEntry] = {}
    by_index: dict[tuple[int, int], ObjectEntry] = {}
    for entry in entries:
        what = "field" if isinstance(entry, Field) else f"hil_{entry.direction.value}"
        if entry.name in by_name:
            raise TableError(f"{source}: {what} {entry.name!r}: duplicate name")
        at = (entry.index, entry.subindex)
        if at in by_index:
            sub = f" sub {entry.subindex}" if entry.subindex else ""
            raise TableError(
                f"{source}: {what} {entry.name!r}: index 0x{entry.index:04X}{sub} "
                f"already used by {by_index[at].name!r}"
            )
        in_profile = isinstance(entry, Field) and entry.index in PROFILE_RANGE
        if entry.index not in MANUFACTURER_RANGE and not in_profile:
            raise TableError(
                f"{source}: {what} {entry.name!r}: index 0x{entry.index:04X} "
                "outside the manufacturer range 0x2000..0x5FFF"
            )
        by_name[entry.name] = entry
        by_index[at] = entry


def _load_recorder(
    source: Path, data: Any, entries: list[ObjectEntry], enums: list[ValueEnum], *, standard: bool
) -> Recorder:
    """The merged [recorder]; `standard`: the board's table has no [recorder] of its own."""
    entry = _Entry(source, "recorder", data)
    entry.check_keys(_RECORDER_KEYS)
    index = entry.integer("index", MANUFACTURER_RANGE.start, MANUFACTURER_RANGE.stop - len(RecorderObject))
    channels = entry.integer("channels", 1, MAX_RECORDER_CHANNELS)
    buffer_values = entry.integer("buffer_values", 1, MAX_RECORDER_VALUES)
    if buffer_values < channels:
        raise entry.error(f"buffer_values {buffer_values} holds not even one sample of {channels} channels")
    recorder = Recorder(index=index, max_channels=channels, buffer_values=buffer_values)
    for other in entries:
        if other.index in recorder.indices:
            offset = RecorderObject(other.index - index)
            move = "; move the standard recorder with [recorder] index = ..." if standard else ""
            raise entry.error(
                f"{offset.object_name} at 0x{other.index:04X} collides with {other.name!r} "
                f"(the recorder takes 0x{index:04X}..0x{recorder.indices[-1]:04X}{move})"
            )
    by_name = {e.name: e for e in enums}  # the standard ones unless the board's replace them
    for name, required in RECORDER_ENUMS.items():
        values = by_name[name]
        missing = [v for v in required if v not in {value.name for value in values.values}]
        if missing:
            raise entry.error(
                f"[[enum]] {name!r} lacks the value{'s' if len(missing) > 1 else ''} {', '.join(missing)}"
            )
        outside = [v for v in values.values if v.value not in _RECORDER_ENUM_RANGE]
        if outside:
            value = outside[0]
            raise entry.error(
                f"[[enum]] {name!r} value {value.name!r} = {value.value} does not fit its UNSIGNED8 object"
            )
    return recorder


def default_cob_id_base(direction: PdoDirection, number: int) -> int | None:
    """CiA 301 pre-defined connection set for PDO 1..4, and the same + 0x40 for 5..8
    (a common extension; there is no standard default beyond PDO 4)."""
    return predefined_pdo_base(RPDO_FUNCTIONS if direction is PdoDirection.RPDO else TPDO_FUNCTIONS, number)


def _load_pdos(
    source: Path,
    document: Mapping[str, Any],
    direction: PdoDirection,
    slot_count: int,
    entries_by_name: Mapping[str, ObjectEntry],
) -> tuple[Pdo, ...]:
    label = direction.value.upper()
    configured: dict[int, Pdo] = {}
    for position, data in enumerate(_array_of_tables(source, document, direction.value)):
        number_hint = data.get("number") if isinstance(data, Mapping) else None
        what = (
            f"{label}{number_hint}"
            if isinstance(number_hint, int)
            else (f"{direction.value} #{position + 1}")
        )
        entry = _Entry(source, what, data)
        entry.check_keys(_PDO_REQUIRED_KEYS, _PDO_OPTIONAL_KEYS)
        if slot_count == 0:
            raise entry.error(f"the node has no {label} slots ([pdo] {direction.value}_slots = 0)")
        number = entry.integer("number", 1, slot_count)
        if number in configured:
            raise entry.error(f"{label}{number} is configured twice")
        pdo = _load_pdo(entry, direction, number, entries_by_name)
        configured[number] = pdo

    slots = []
    for number in range(1, slot_count + 1):
        if number in configured:
            slots.append(configured[number])
            continue
        base = default_cob_id_base(direction, number)
        slots.append(
            Pdo(
                direction=direction,
                number=number,
                cob_id_base=base or 0,
                enabled=False,
                transmission_type=255,
                inhibit_time_100us=0,
                event_timer_ms=0,
                entries=(),
            )
        )
    _check_cob_id_collisions(source, slots)
    return tuple(slots)


def _load_pdo(
    entry: _Entry, direction: PdoDirection, number: int, entries_by_name: Mapping[str, ObjectEntry]
) -> Pdo:
    standard_type = STANDARD_TRANSMISSION_TYPES[direction]
    transmission_type = entry.integer("transmission_type", 0, 255, default=standard_type)
    if transmission_type not in _TRANSMISSION_TYPES:
        raise entry.error(
            f"transmission_type {transmission_type} is not supported "
            "(0..240 synchronous, 254/255 event driven)"
        )
    enabled = entry.boolean("enabled", default=True)
    default_base = default_cob_id_base(direction, number)
    if "cob_id_base" not in entry.data and default_base is None:
        raise entry.error(f"{direction.value.upper()}{number} has no default COB-ID: set cob_id_base")
    # The largest COB-ID (base + node id 127) must still be an 11-bit identifier.
    cob_id_base = entry.integer("cob_id_base", 1, 0x7FF - MAX_NODE_ID, default=default_base)

    names = entry.data["map"]
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise entry.error("map must be a list of object names")
    if len(names) > MAX_PDO_ENTRIES:
        raise entry.error(f"maps {len(names)} objects, at most {MAX_PDO_ENTRIES} fit")
    mapped: list[PdoEntry] = []
    for name in names:
        if name not in entries_by_name:
            raise entry.error(
                "maps an unknown object: "
                + unknown_name_message("board field or HIL I/O object", name, entries_by_name)
            )
        if any(m.name == name for m in mapped):
            raise entry.error(f"maps {name!r} twice")
        target = entries_by_name[name]
        if direction is PdoDirection.RPDO and target.access is not Access.READ_WRITE:
            raise entry.error(
                f"maps {name!r}, which is read-only over the bus; an RPDO can only write rw objects"
            )
        mapped.append(PdoEntry(name=name, index=target.index, subindex=target.subindex, bits=target.bits))
    total_bits = sum(m.bits for m in mapped)
    if total_bits > MAX_PDO_BITS:
        raise entry.error(
            f"mapping is {total_bits} bits long, a PDO holds at most {MAX_PDO_BITS} bits (8 bytes)"
        )
    return Pdo(
        direction=direction,
        number=number,
        cob_id_base=cob_id_base,
        enabled=enabled,
        transmission_type=transmission_type,
        inhibit_time_100us=entry.integer("inhibit_time_100us", 0, 0xFFFF, default=0),
        event_timer_ms=entry.integer("event_timer_ms", 0, 0xFFFF, default=0),
        entries=tuple(mapped),
        sync_start=entry.integer("sync_start", 0, LAST_SYNCHRONOUS_TYPE, default=0),  # boardproto.profiles
    )


def _check_cob_id_collisions(source: Path, slots: list[Pdo]) -> None:
    seen: dict[int, Pdo] = {}
    for pdo in slots:
        if not pdo.enabled:
            continue
        if pdo.cob_id_base in seen:
            raise TableError(
                f"{source}: {pdo.name}: COB-ID base 0x{pdo.cob_id_base:X} "
                f"already used by {seen[pdo.cob_id_base].name}"
            )
        seen[pdo.cob_id_base] = pdo


def _slot_count(section: _Entry, document: Mapping[str, Any], direction: PdoDirection) -> int:
    """[pdo]'s rpdo_slots or tpdo_slots, else as many as boardproto.standard gives the table."""
    standard = min(pdo_slots(document, direction), MAX_PDO_SLOTS)
    return section.integer(f"{direction.value}_slots", 0, MAX_PDO_SLOTS, default=standard)


def parse_table(source: Path, document: Mapping[str, Any]) -> BoardTable:
    """Validate an already parsed TOML document; `source` only names it in errors."""
    for key in document:
        if key not in _TOP_LEVEL_KEYS:
            raise TableError(
                f"{source}: "
                + unknown_name_message("top-level table", key, sorted(_TOP_LEVEL_KEYS)).replace(
                    "no top-level table named", "unknown top-level table"
                )
            )
    if "node" not in document:
        raise TableError(f"{source}: missing [node] table")
    own_recorder = "recorder" in document
    own_emcy = len(_array_of_tables(source, document, "emcy"))
    document = merge_standard(document)

    node = _load_node(source, document["node"])
    fields = [_load_field(source, i, d) for i, d in enumerate(_array_of_tables(source, document, "field"))]
    if not fields:
        raise TableError(f"{source}: defines no [[field]]")
    inputs = [
        _load_hil_io(source, IoDirection.INPUT, i, d)
        for i, d in enumerate(_array_of_tables(source, document, "hil_input"))
    ]
    outputs = [
        _load_hil_io(source, IoDirection.OUTPUT, i, d)
        for i, d in enumerate(_array_of_tables(source, document, "hil_output"))
    ]
    all_entries: list[ObjectEntry] = [*fields, *inputs, *outputs]
    _check_unique(source, all_entries)
    from boardproto.arrays import load_arrays  # built on this module's helpers

    arrays = load_arrays(source, _array_of_tables(source, document, "array"), all_entries)
    entries_by_name = {e.name: e for e in all_entries}

    emcy = [_load_emcy(source, i, d) for i, d in enumerate(_array_of_tables(source, document, "emcy"))]
    _unique_names(source, "emcy", emcy)
    for i, code in enumerate(emcy):
        first = next((other for other in emcy[:i] if other.code == code.code), None)
        if first is not None and i >= own_emcy:  # the board's own come first, then the standard ones
            raise TableError(
                f"{source}: emcy {first.name!r}: code 0x{code.code:04X} is the standard {code.name!r}'s "
                f"(boardproto.standard): name yours {code.name!r} to replace it, or pick another code"
            )
        if first is not None:
            raise TableError(
                f"{source}: emcy {code.name!r}: code 0x{code.code:04X} already used by {first.name!r}"
            )
    emcy_by_name = {e.name: e for e in emcy}
    enums = [_load_enum(source, i, d) for i, d in enumerate(_array_of_tables(source, document, "enum"))]
    _unique_names(source, "enum", enums)
    bitsets = [
        _load_bitset(source, i, d, emcy_by_name, entries_by_name)
        for i, d in enumerate(_array_of_tables(source, document, "bitset"))
    ]
    _unique_names(source, "bitset", bitsets)
    _check_values(source, all_entries, enums, bitsets)

    pdo_section = _Entry(source, "pdo", document.get("pdo", {}))
    pdo_section.check_keys(frozenset(), _PDO_SLOT_KEYS)
    rpdos = _load_pdos(
        source,
        document,
        PdoDirection.RPDO,
        _slot_count(pdo_section, document, PdoDirection.RPDO),
        entries_by_name,
    )
    tpdos = _load_pdos(
        source,
        document,
        PdoDirection.TPDO,
        _slot_count(pdo_section, document, PdoDirection.TPDO),
        entries_by_name,
    )
    from boardproto.profiles import load_pdo_profiles  # built on this module's helpers

    profiles = load_pdo_profiles(source, document, (len(rpdos), len(tpdos)), entries_by_name, (rpdos, tpdos))

    recorder = _load_recorder(source, document["recorder"], all_entries, enums, standard=not own_recorder)

    return BoardTable(
        source=source,
        node=node,
        fields=tuple(fields),
        hil_inputs=tuple(inputs),
        hil_outputs=tuple(outputs),
        rpdos=rpdos,
        tpdos=tpdos,
        enums=tuple(enums),
        bitsets=tuple(bitsets),
        emcy_codes=tuple(emcy),
        recorder=recorder,
        pdo_profiles=profiles,
        arrays=arrays,
    )


def load_table(path: str | Path) -> BoardTable:
    """Read and validate board.toml. Raises TableError (a ValueError) on any problem."""
    source = Path(path)
    try:
        with source.open("rb") as file:
            document = tomllib.load(file)
    except OSError as error:
        raise TableError(f"{source}: cannot read: {error.strerror}") from error
    except UnicodeDecodeError as error:  # TOML is UTF-8; tomllib lets the decode error through
        raise TableError(f"{source}: not UTF-8 text: byte {error.start}: {error.reason}") from error
    except tomllib.TOMLDecodeError as error:
        raise TableError(f"{source}: not valid TOML: {error}") from error
    return parse_table(source, document)
