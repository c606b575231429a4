"""Generate `board/fields.hpp`: the firmware's view of the board table (namespace board)."""

from __future__ import annotations

from boardproto.loader import TableError
from boardproto.recording import FIXED_HEADER_BYTES, HEADER_FIELDS, LAYOUT_VERSION
from boardproto.table import (
    BitSet,
    BoardTable,
    DataType,
    EmcyCode,
    ErrorRegisterBit,
    Field,
    FlagBit,
    HilIo,
    Pdo,
    Recorder,
    RecorderObject,
    RecorderStatusSub,
    RecorderTriggerSub,
    ValueEnum,
    camel_case,
)

GENERATED_BANNER = "// Generated from protocol/board.toml by protocol/boardproto. Do not edit."
"""The banner of the default table's files; another table's names that table (`banner`)."""


def table_name(table: BoardTable) -> str:
    """The table's path from the protocol/ folder on ("protocol/boards/head.toml"), or its file
    name when it lives elsewhere (another project's table)."""
    parts = table.source.resolve().parts if table.source.is_absolute() else table.source.parts
    if "protocol" in parts:
        at = len(parts) - 1 - parts[::-1].index("protocol")
        return "/".join(parts[at:])
    return table.source.name


def banner(table: BoardTable) -> str:
    """The first line of every file generated from `table`."""
    return GENERATED_BANNER.replace("protocol/board.toml", table_name(table))


PDO_MAX_ENTRIES = 8


def cpp_string(text: str) -> str:
    """A C++ string literal; the loader already limits text to printable ASCII."""
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def cpp_float(value: float) -> str:
    """A float literal the compiler rounds exactly as strtof() rounds repr(value)."""
    text = repr(float(value))
    if "e" not in text and "." not in text:
        text += ".0"
    return text + "f"


def _field_initializer(field: Field) -> str:
    return (
        f"    {{.name = {cpp_string(field.name)}, .index = 0x{field.index:04X}, "
        f".subindex = {field.subindex}, .unit = {cpp_string(field.unit)},\n"
        f"     .kind = Kind::{field.kind.cpp_name}, .access = Access::{field.access.cpp_name},\n"
        f"     .min = {cpp_float(field.min)}, .max = {cpp_float(field.max)}, "
        f".default_value = {cpp_float(field.default)}, "
        f".stored = {'true' if field.stored else 'false'}, "
        f".type = DataType::{field.data_type.cpp_name},\n"
        f"     .description = {cpp_string(field.description)}}},"
    )


def _io_initializer(io: HilIo) -> str:
    return (
        f"    {{.name = {cpp_string(io.name)}, .index = 0x{io.index:04X}, "
        f".type = DataType::{io.data_type.cpp_name}, .min = {io.min}, .max = {io.max},\n"
        f"     .unit = {cpp_string(io.unit)}, .description = {cpp_string(io.description)}}},"
    )


def _pdo_initializer(pdo: Pdo) -> str:
    entries = [f"{{0x{e.index:04X}, {e.subindex}, {e.bits}}}" for e in pdo.entries]
    entries += ["{0, 0, 0}"] * (PDO_MAX_ENTRIES - len(entries))
    mapped = ", ".join(e.name for e in pdo.entries) or "nothing"
    return (
        f"    // {pdo.name}: {mapped}\n"
        f"    {{.number = {pdo.number}, .cob_id_base = 0x{pdo.cob_id_base:03X}, "
        f".enabled = {'true' if pdo.enabled else 'false'}, "
        f".transmission_type = {pdo.transmission_type},\n"
        f"     .inhibit_time_100us = {pdo.inhibit_time_100us}, "
        f".event_timer_ms = {pdo.event_timer_ms}, .count = {len(pdo.entries)},\n"
        f"     .entries = {{{{{', '.join(entries)}}}}}}},"
    )


def _enumerators(names: list[str], comments: list[str]) -> str:
    width = max((len(n) for n in names), default=0) + 1
    lines = [
        f"  {(name + ','):<{width}}  // {comment}" for name, comment in zip(names, comments, strict=True)
    ]
    return "\n".join([*lines, "  kCount"])


def _data_type_enumerators() -> str:
    return ",\n".join(f"  {t.cpp_name} = 0x{t.value:04X}" for t in DataType)


# Smallest integer type that holds every value of an [[enum]] (values fit in 25 bits signed).
_ENUM_TYPES = (
    ("std::uint8_t", 0, 0xFF),
    ("std::int8_t", -0x80, 0x7F),  # protocol-literal: the int8 range
    ("std::uint16_t", 0, 0xFFFF),
    ("std::int16_t", -0x8000, 0x7FFF),
    ("std::int32_t", -0x8000_0000, 0x7FFF_FFFF),
)

# C++ types the header declares itself: an [[enum]] or [[bitset]] must not take their names.
_FIXED_TYPE_NAMES = frozenset(
    {
        "FieldId",
        "Kind",
        "Access",
        "DataType",
        "FieldInfo",
        "HilInputId",
        "HilOutputId",
        "IoInfo",
        "NodeIdentity",
        "PdoMapEntry",
        "PdoDefault",
        "EmcyId",
        "EmcyInfo",
        "FlagInfo",
        "RecorderInfo",
    }
)


def cpp_comment(text: str) -> str:
    """Text for the rest of a // line: a trailing backslash would splice the next line in."""
    return text + "." if text.endswith("\\") else text


def enum_underlying_type(values: ValueEnum) -> str:
    """The narrowest of uint8/int8/uint16/int16/int32 that holds every value."""
    numbers = [v.value for v in values.values]
    return next(name for name, low, high in _ENUM_TYPES if low <= min(numbers) and max(numbers) <= high)


def bit_type_name(bitset: BitSet) -> str:
    """fault_flags -> FaultFlagsBit: the enum class of its bit numbers."""
    return f"{bitset.type_name}Bit"


def bits_by_number(bitset: BitSet) -> tuple[FlagBit, ...]:
    """The bits lowest first (the order of the generated arrays)."""
    return tuple(sorted(bitset.bits, key=lambda b: b.bit))


def _check_cpp_names(table: BoardTable) -> None:
    """The C++ names made from board.toml names must not collide (CamelCase joins words:
    'a_1b' and 'a1b' both become A1b; an enum 'kind' would redefine board::Kind)."""
    taken: dict[str, str] = {name: "a type of the header itself" for name in _FIXED_TYPE_NAMES}
    named: list[tuple[str, str, str, list[str]]] = [
        ("enum", e.name, e.type_name, [v.name for v in e.values]) for e in table.enums
    ]
    named += [("bitset", b.name, bit_type_name(b), [bit.name for bit in b.bits]) for b in table.bitsets]
    for what, name, type_name, members in named:
        where = f"{table.source}: {what} {name!r}"
        if type_name in taken:
            raise TableError(f"{where}: its C++ type name {type_name} is already {taken[type_name]}")
        taken[type_name] = f"the type of {what} {name!r}"
        enumerators: dict[str, str] = {}
        for member in members:
            cpp_name = camel_case(member)
            if cpp_name in enumerators:
                raise TableError(
                    f"{where}: {member!r} and {enumerators[cpp_name]!r} both become the C++ name {cpp_name}"
                )
            enumerators[cpp_name] = member


# The recorder objects that carry its enums' values (the loader requires these enums).
_RECORDER_CARRIERS = {
    "recorder_state": (RecorderObject.STATE, 0),
    "recorder_trigger": (RecorderObject.TRIGGER, RecorderTriggerSub.SOURCE),
    "recorder_edge": (RecorderObject.TRIGGER, RecorderTriggerSub.EDGE),
}


def _carried_by(table: BoardTable, name: str) -> str:
    carriers = [f"{e.name} (0x{e.index:04X})" for e in table.entries if e.values == name]
    if table.recorder is not None and name in _RECORDER_CARRIERS:
        recorder_object, sub = _RECORDER_CARRIERS[name]
        carriers.append(
            f"{recorder_object.object_name} (0x{table.recorder.index_of(recorder_object):04X} sub {sub})"
        )
    return ", ".join(carriers) or "no field yet"


def _aligned_enumerators(items: list[tuple[str, str]]) -> str:
    """`Name = value,  // comment` lines, the comments aligned."""
    width = max(len(code) for code, _ in items) + 1
    return "\n".join(f"  {(code + ','):<{width}}  // {cpp_comment(comment)}" for code, comment in items)


def _brace_list(items: list[str]) -> str:
    """`{a, b}` on one line when short, else one item a line."""
    one_line = "{" + ", ".join(items) + "}"
    if len(one_line) <= 60:
        return one_line
    return "{\n" + "".join(f"    {item},\n" for item in items) + "}"


def _switch_to_string(type_name: str, argument: str, members: list[str]) -> str:
    cases = "\n".join(f'    case {type_name}::{camel_case(m)}: return "{m}";' for m in members)
    return f"""constexpr std::string_view to_string({type_name} {argument}) {{
  switch ({argument}) {{
{cases}
  }}
  return {{}};
}}"""


def _value_enum(table: BoardTable, values: ValueEnum) -> str:
    type_name = values.type_name
    underlying = enum_underlying_type(values)
    enumerators = _aligned_enumerators(
        [(f"{camel_case(v.name)} = {v.value}", v.description) for v in values.values]
    )
    listed = _brace_list([f"{type_name}::{camel_case(v.name)}" for v in values.values])
    return f"""// {values.name}: {cpp_comment(values.description)}
// Carried by: {_carried_by(table, values.name)}.
enum class {type_name} : {underlying} {{
{enumerators}
}};
inline constexpr std::array<{type_name}, {len(values.values)}> k{type_name}Values = {listed};
// The number its field carries.
constexpr float to_value({type_name} value) {{ return static_cast<float>(static_cast<{underlying}>(value)); }}
// The name in board.toml; empty for a number that is none of the values.
{_switch_to_string(type_name, "value", [v.name for v in values.values])}
// The value a field's number is exactly; std::nullopt for any other number.
constexpr std::optional<{type_name}> {values.name}_from_value(float value) {{
  return from_value(k{type_name}Values, value);
}}
"""


def _flag_info_initializer(table: BoardTable, bit: FlagBit) -> str:
    emcy = f"EmcyId::{bit.emcy}" if bit.emcy is not None else "std::nullopt"
    if bit.about is None:
        about = "std::nullopt"
        about_comment = "the raiser names the object" if bit.emcy is not None else "raises no EMCY"
    else:
        about = f"std::uint16_t{{0x{table.entry(bit.about).index:04X}}}"
        about_comment = f"about {bit.about}"
    return (
        f"    // bit {bit.bit}: {about_comment}\n"
        f"    {{.name = {cpp_string(bit.name)}, .bit = {bit.bit}, .emcy = {emcy}, .about_index = {about},\n"
        f"     .description = {cpp_string(bit.description)}}},"
    )


def _bitset(table: BoardTable, bitset: BitSet) -> str:
    type_name = bit_type_name(bitset)
    bits = bits_by_number(bitset)
    enumerators = _aligned_enumerators([(f"{camel_case(b.name)} = {b.bit}", b.description) for b in bits])
    listed = _brace_list([f"{type_name}::{camel_case(b.name)}" for b in bits])
    all_bits = sum(b.mask for b in bits)
    infos = "\n".join(_flag_info_initializer(table, b) for b in bits)
    return f"""// {bitset.name}: {cpp_comment(bitset.description)}
// Carried by: {_carried_by(table, bitset.name)}. The enumerators are bit numbers.
enum class {type_name} : std::uint8_t {{
{enumerators}
}};
// Every bit, lowest first.
inline constexpr std::array<{type_name}, {len(bits)}> k{bitset.type_name}Bits = {listed};
// Every named bit set.
inline constexpr std::uint32_t k{bitset.type_name}Mask = 0x{all_bits:08X};
constexpr std::uint32_t mask({type_name} bit) {{
  return std::uint32_t{{1}} << static_cast<std::uint8_t>(bit);
}}
// The name in board.toml; empty for a number that is none of the bits.
{_switch_to_string(type_name, "bit", [b.name for b in bits])}
// Each bit and the EMCY it raises when it latches, lowest bit first.
inline constexpr std::array<FlagInfo, {len(bits)}> k{bitset.type_name}Info = {{{{
{infos}
}}}};
"""


def _error_register_constants() -> str:
    return "\n".join(
        f"inline constexpr std::uint8_t k{camel_case(bit.toml_name)} = 0x{bit.value:02X};"
        + ("  // set whenever any error is active" if bit is ErrorRegisterBit.GENERIC else "")
        for bit in ErrorRegisterBit
    )


def _register_constant(code: EmcyCode) -> str:
    return f"error_register::k{camel_case(code.error_register.toml_name)}"


def _emcy_initializer(code: EmcyCode) -> str:
    return (
        f"    {{.name = {cpp_string(code.name)}, .code = 0x{code.code:04X}, "
        f".register_bit = {_register_constant(code)},\n"
        f"     .description = {cpp_string(code.description)}}},"
    )


def _emcy_section(table: BoardTable) -> str:
    codes = table.emcy_codes
    ids = _enumerators(
        [c.name for c in codes],
        [f"0x{c.code:04X}, error register: {c.error_register.toml_name}" for c in codes],
    )
    infos = "\n".join(_emcy_initializer(c) for c in codes)
    declarations = [
        f"inline constexpr std::uint16_t k{camel_case(c.name)} = info(EmcyId::{c.name}).code;" for c in codes
    ]
    width = max((len(d) for d in declarations), default=0)
    constants = "\n".join(
        f"{d:<{width}}  // 0x{c.code:04X}" for d, c in zip(declarations, codes, strict=True)
    )
    return f"""// ---------------------------------------------------------------------------
// Emergency (EMCY) codes the firmware raises (CiA 301, 7.2.7.1). Each sets one bit of the
// error register 0x1001; the frame's 5 manufacturer bytes start with the object index (LE)
// the error is about.
// ---------------------------------------------------------------------------
// Bits of the error register 0x1001 (CiA 301, 7.5.2.2).
namespace error_register {{
{_error_register_constants()}
}}  // namespace error_register

enum class EmcyId : std::uint8_t {{
{ids}
}};
inline constexpr std::size_t kEmcyCount = static_cast<std::size_t>(EmcyId::kCount);

struct EmcyInfo {{
  std::string_view name;        // snake_case, as in board.toml
  std::uint16_t code;           // the frame's error code
  std::uint8_t register_bit;    // the bit of 0x1001 it sets (error_register::k...)
  std::string_view description;
}};

inline constexpr std::array<EmcyInfo, kEmcyCount> kEmcyCodes = {{{{
{infos}
}}}};

constexpr const EmcyInfo& info(EmcyId id) {{ return kEmcyCodes[static_cast<std::size_t>(id)]; }}

// The codes by name.
namespace emcy_code {{
{constants}
}}  // namespace emcy_code
"""


def _visitor(name: str, calls: list[str]) -> str:
    if not calls:
        return f"template <typename Visit>\nconstexpr void {name}(Visit&&) {{}}"
    body = "\n".join(f"  visit({call});" for call in calls)
    return f"template <typename Visit>\nconstexpr void {name}(Visit&& visit) {{\n{body}\n}}"


def _values_section(table: BoardTable) -> str:
    enums = "\n".join(_value_enum(table, e) for e in table.enums)
    bitsets = "\n".join(_bitset(table, b) for b in table.bitsets)
    each_enum = _visitor(
        "for_each_enum", [f'std::string_view{{"{e.name}"}}, k{e.type_name}Values' for e in table.enums]
    )
    each_bitset = _visitor(
        "for_each_bitset",
        [f'std::string_view{{"{b.name}"}}, k{b.type_name}Bits, k{b.type_name}Info' for b in table.bitsets],
    )
    return f"""// ---------------------------------------------------------------------------
// Values that travel in fields ([[enum]] and [[bitset]]). A field carries them as a
// float; what a number that is none of them means is the reader's rule, not the table's.
// ---------------------------------------------------------------------------
// The value of `values` a field's number is exactly; std::nullopt for any other number.
template <typename Value, std::size_t N>
constexpr std::optional<Value> from_value(const std::array<Value, N>& values, float number) {{
  for (const Value value : values) {{
    if (to_value(value) == number) return value;
  }}
  return std::nullopt;
}}

// A bit of a [[bitset]] and what it reports on the bus when it latches.
struct FlagInfo {{
  std::string_view name;                     // snake_case, as in board.toml
  std::uint8_t bit;                          // bit number: the flag's value is 1 << bit
  std::optional<EmcyId> emcy;                // raised when the bit latches; std::nullopt: none
  std::optional<std::uint16_t> about_index;  // object index in the EMCY's manufacturer bytes;
                                             // std::nullopt: the raiser names it at run time
  std::string_view description;

  constexpr std::uint32_t mask() const {{ return std::uint32_t{{1}} << bit; }}
}};

{enums}
{bitsets}
// Every [[enum]] and [[bitset]], for code that walks them all (the cross-check test):
// visit(name, values) per enum, visit(name, bits, info) per bitset.
{each_enum}
{each_bitset}
"""


# The field whose latched bits the firmware application turns into EMCY frames every cycle, and
# the bit of its [[bitset]] a refused write latches (platform/linux/hilfw/BoardRuntime.cpp).
FAULT_FLAGS_FIELD = "fault_flags"
OWNERSHIP_VIOLATION_BIT = "ownership_violation"


def _fault_flags_section(table: BoardTable) -> str:
    bitset_names = {b.name for b in table.bitsets}
    field = next((f for f in table.fields if f.name == FAULT_FLAGS_FIELD and f.values in bitset_names), None)
    if field is None:
        field_id, bits, ownership = "std::nullopt", "{}", "std::nullopt"
        carried = f"this table has no field {FAULT_FLAGS_FIELD} carrying a [[bitset]]: none"
    else:
        bitset = table.bitset(str(field.values))
        field_id, bits = f"FieldId::{field.name}", f"k{bitset.type_name}Info"
        ownership_bits = [b.bit for b in bitset.bits if b.name == OWNERSHIP_VIOLATION_BIT]
        ownership = f"std::uint8_t{{{ownership_bits[0]}}}" if ownership_bits else "std::nullopt"
        carried = f"the field {field.name} and its [[bitset]] {bitset.name}"
    return f"""// ---------------------------------------------------------------------------
// The fault flags the firmware application reports: after every cycle, bits of this field that
// latched become EMCY frames, as their FlagInfo says ({carried}).
// ---------------------------------------------------------------------------
inline constexpr std::optional<FieldId> kFaultFlagsField = {field_id};
inline constexpr std::span<const FlagInfo> kFaultFlagsEmcy = {bits};
// The bit a refused write latches ({OWNERSHIP_VIOLATION_BIT}); std::nullopt: none.
inline constexpr std::optional<std::uint8_t> kOwnershipViolationBit = {ownership};
"""


def _constants(type_name: str, items: list[tuple[str, int, str]], width: int = 4) -> str:
    """`inline constexpr <type> k<Name> = 0x...;  // comment` lines."""
    spelled = [(name, str(value) if width == 0 else f"0x{value:0{width}X}") for name, value, _ in items]
    lines = [f"inline constexpr {type_name} k{camel_case(name)} = {value};" for name, value in spelled]
    column = max(len(line) for line in lines)
    return "\n".join(
        f"{line:<{column}}  // {comment}" if comment else line
        for line, (_, _, comment) in zip(lines, items, strict=True)
    )


_RECORDER_OBJECT_COMMENTS = {
    RecorderObject.STATE: "UNSIGNED8 rw: a RecorderState; write Armed to (re-)arm, Idle to stop",
    RecorderObject.CHANNELS: "ARRAY rw: sub 0 channels in use, sub n a field's object index",
    RecorderObject.DIVIDER: "UNSIGNED16 rw: one sample every n-th control cycle",
    RecorderObject.SAMPLES: "UNSIGNED32 rw: samples per recording",
    RecorderObject.TRIGGER: "RECORD rw: sub-indices in recorder::trigger_sub",
    RecorderObject.STATUS: "RECORD ro: sub-indices in recorder::status_sub",
    RecorderObject.DATA: "DOMAIN ro: the recording (layout in recorder::recording)",
}


def _recorder_section(recorder: Recorder) -> str:
    objects = _constants(
        "std::uint16_t",
        [(o.name.lower(), recorder.index_of(o), _RECORDER_OBJECT_COMMENTS[o]) for o in RecorderObject],
    )
    trigger = _constants(
        "std::uint8_t",
        [(s.name.lower(), int(s), "") for s in RecorderTriggerSub]
        + [("highest", max(RecorderTriggerSub), "sub 0 reads this")],
        width=0,
    )
    status = _constants(
        "std::uint8_t",
        [(s.name.lower(), int(s), "") for s in RecorderStatusSub]
        + [("highest", max(RecorderStatusSub), "sub 0 reads this")],
        width=0,
    )
    offsets = "\n".join(
        f"inline constexpr std::size_t k{camel_case(name)}Offset = {offset};  // {ctype}"
        for name, offset, ctype in HEADER_FIELDS
    )
    return f"""// ---------------------------------------------------------------------------
// Field recorder ([recorder] in board.toml): samples chosen board fields at the end of every
// control cycle into static memory around a trigger; the host uploads the recording (DOMAIN).
// Its states, trigger sources and edges are the [[enum]]s RecorderState, RecorderTrigger and
// RecorderEdge above.
// ---------------------------------------------------------------------------
struct RecorderInfo {{
  std::uint16_t index;            // the first object (recorder_state); the rest follow
  std::uint8_t max_channels;      // channel array sub-indices 1..max_channels
  std::uint32_t buffer_values;    // REAL32 values of sample memory (samples * channels)
  std::uint32_t default_samples;  // samples per recording at power-on
}};

inline constexpr RecorderInfo kRecorder = {{
    .index = 0x{recorder.index:04X},
    .max_channels = {recorder.max_channels},
    .buffer_values = {recorder.buffer_values},
    .default_samples = {recorder.default_samples},
}};

namespace recorder {{
// Object indices.
{objects}

// Sub-indices of the trigger record.
namespace trigger_sub {{
{trigger}
}}  // namespace trigger_sub

// Sub-indices of the status record.
namespace status_sub {{
{status}
}}  // namespace status_sub

// The bytes of recorder_data (protocol/boardproto/recording.py), little-endian: the fixed header
// at these offsets, then the channels' field indices (UNSIGNED16 each) from kChannelsOffset,
// then from header_bytes on the samples (REAL32 [samples][channels], oldest first).
namespace recording {{
inline constexpr std::uint8_t kLayoutVersion = {LAYOUT_VERSION};
inline constexpr std::size_t kFixedHeaderBytes = {FIXED_HEADER_BYTES};
{offsets}
// Where sample 0 starts: the fixed header and the channel indices, rounded up to 4 bytes.
constexpr std::size_t header_bytes(std::size_t channels) {{
  return (kFixedHeaderBytes + 2 * channels + 3) / 4 * 4;
}}
}}  // namespace recording
}}  // namespace recorder
"""


def generate_header(table: BoardTable) -> str:
    """The whole header text. Deterministic: same table, same bytes."""
    _check_cpp_names(table)
    node = table.node
    field_ids = _enumerators(
        [f.name for f in table.fields],
        [
            f"0x{f.index:04X}{f' sub {f.subindex}' if f.subindex else ''} [{f.unit}] "
            f"{f.kind.value}, {f.access.value}"
            for f in table.fields
        ],
    )
    input_ids = _enumerators(
        [io.name for io in table.hil_inputs],
        [f"0x{io.index:04X} {io.data_type.toml_name} [{io.unit}]" for io in table.hil_inputs],
    )
    output_ids = _enumerators(
        [io.name for io in table.hil_outputs],
        [f"0x{io.index:04X} {io.data_type.toml_name} [{io.unit}]" for io in table.hil_outputs],
    )
    fields = "\n".join(_field_initializer(f) for f in table.fields)
    arrays = "\n".join(
        f"    {{.name = {cpp_string(a.name)}, .index = 0x{a.index:04X}, .count = {a.count}}},"
        for a in table.arrays
    )
    inputs = "\n".join(_io_initializer(io) for io in table.hil_inputs)
    outputs = "\n".join(_io_initializer(io) for io in table.hil_outputs)
    rpdos = "\n".join(_pdo_initializer(p) for p in table.rpdos)
    tpdos = "\n".join(_pdo_initializer(p) for p in table.tpdos)

    return f"""{banner(table)}
// Board fields, hardware-in-the-loop I/O objects, node identity, default PDOs, EMCY codes and
// the values fields carry (enums, flag bits).
// Edit {table_name(table)} and rebuild; the EDS and DBC beside this header come from
// the same table.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>

namespace board {{

// ---------------------------------------------------------------------------
// Board fields. A field is a REAL32 object at (index, sub-index 0), a profile object's integer
// type in the profile range, or sub-index 1..n of an ARRAY (kFieldArrays).
// ---------------------------------------------------------------------------
enum class FieldId : std::uint16_t {{
{field_ids}
}};
inline constexpr std::size_t kFieldCount = static_cast<std::size_t>(FieldId::kCount);

// Which kind of component writes the field (Command and Parameter: the CANopen node).
enum class Kind : std::uint8_t {{ Sensor, VirtualSensor, Module, Actuator, Command, Parameter }};
// Access over the bus.
enum class Access : std::uint8_t {{ ReadOnly, ReadWrite }};
// CANopen data types; the values ARE the CiA 301 data type codes.
enum class DataType : std::uint16_t {{
{_data_type_enumerators()}
}};

struct FieldInfo {{
  std::string_view name;        // snake_case, as in board.toml
  std::uint16_t index;          // object index: 0x2000..0x5FFF, a profile's 0x6000..
  std::uint8_t subindex;        // 0, or 1..n in the ARRAY at `index` (kFieldArrays)
  std::string_view unit;        // "rad", "rad/s", "N*m", "degC", "ohm", "1" ...
  Kind kind;
  Access access;
  float min, max, default_value;
  bool stored;                  // saved by 0x1010 "store parameters"
  DataType type;                // on the bus: Real32, or a device profile object's integer type
  std::string_view description;
}};

inline constexpr std::array<FieldInfo, kFieldCount> kFields = {{{{
{fields}
}}}};

constexpr const FieldInfo& info(FieldId id) {{ return kFields[static_cast<std::size_t>(id)]; }}

// CiA 301 ARRAYs of board fields ([[array]] in board.toml): sub 0 the number of members
// (UNSIGNED8, read-only), sub 1..count the fields at `index` with that sub-index.
struct FieldArrayInfo {{
  std::string_view name;
  std::uint16_t index;
  std::uint8_t count;           // the highest sub-index
}};
inline constexpr std::size_t kFieldArrayCount = {len(table.arrays)};
inline constexpr std::array<FieldArrayInfo, kFieldArrayCount> kFieldArrays = {{{{
{arrays}
}}}};

// ---------------------------------------------------------------------------
// Hardware-in-the-loop I/O objects: NOT board fields; driver registers in the
// object dictionary. Inputs = raw sensor values the rig injects (RPDO, rw),
// outputs = raw actuator values the firmware sends (TPDO, ro).
// ---------------------------------------------------------------------------
enum class HilInputId : std::uint8_t {{
{input_ids}
}};
enum class HilOutputId : std::uint8_t {{
{output_ids}
}};
inline constexpr std::size_t kHilInputCount = static_cast<std::size_t>(HilInputId::kCount);
inline constexpr std::size_t kHilOutputCount = static_cast<std::size_t>(HilOutputId::kCount);

struct IoInfo {{
  std::string_view name;
  std::uint16_t index;          // object index, sub-index 0
  DataType type;
  std::int64_t min, max;        // raw integer range
  std::string_view unit;
  std::string_view description;
}};

inline constexpr std::array<IoInfo, kHilInputCount> kHilInputs = {{{{
{inputs}
}}}};
inline constexpr std::array<IoInfo, kHilOutputCount> kHilOutputs = {{{{
{outputs}
}}}};

constexpr const IoInfo& info(HilInputId id) {{ return kHilInputs[static_cast<std::size_t>(id)]; }}
constexpr const IoInfo& info(HilOutputId id) {{ return kHilOutputs[static_cast<std::size_t>(id)]; }}

// ---------------------------------------------------------------------------
// Node identity (0x1000, 0x1008..0x100A, 0x1017, 0x1018) and the sizes of 0x1003 and 0x1016.
// ---------------------------------------------------------------------------
struct NodeIdentity {{
  std::uint32_t device_type;
  std::uint32_t vendor_id;
  std::uint32_t product_code;
  std::uint32_t revision;
  std::string_view device_name;
  std::string_view hardware_version;
  std::string_view software_version;
  std::uint8_t default_node_id;
  std::uint16_t heartbeat_ms;
  std::uint32_t period_us;      // the control period of a start without --period-us
  std::uint32_t period_us_min;  // the control periods --period-us accepts
  std::uint32_t period_us_max;
  std::uint32_t boot_ms;        // NMT reset -> boot-up (control time in lockstep, else wall clock)
}};

inline constexpr NodeIdentity kNode = {{
    .device_type = 0x{node.device_type:08X},
    .vendor_id = 0x{node.vendor_id:08X},
    .product_code = 0x{node.product_code:08X},
    .revision = 0x{node.revision:08X},
    .device_name = {cpp_string(node.device_name)},
    .hardware_version = {cpp_string(node.hardware_version)},
    .software_version = {cpp_string(node.software_version)},
    .default_node_id = 0x{node.default_node_id:02X},
    .heartbeat_ms = {node.heartbeat_ms},
    .period_us = {node.period_us},
    .period_us_min = {node.period_us_min},
    .period_us_max = {node.period_us_max},
    .boot_ms = {node.boot_ms},
}};

// Number of entries of 0x1003 "pre-defined error field" (sub-indices 1..n).
inline constexpr std::size_t kErrorHistoryLength = {node.error_history_length};

// The microcontroller's cycle budget: the worst control cycle takes at most
// kCycleBudgetPercent % of the period at kMcuClockHz (the Cortex-M build checks it under qemu).
inline constexpr std::uint32_t kMcuClockHz = {node.mcu_clock_hz};
inline constexpr std::uint32_t kCycleBudgetPercent = {node.cycle_budget_percent};

// Number of entries of 0x1016 "consumer heartbeat time" (sub-indices 1..n): the heartbeats of up
// to n other nodes the node watches. Each entry: bits 16..23 node id, bits 0..15 time in ms.
inline constexpr std::size_t kHeartbeatConsumers = {node.heartbeat_consumers};

// ---------------------------------------------------------------------------
// Default PDO configuration (what the node starts with and restores to).
// ---------------------------------------------------------------------------
struct PdoMapEntry {{ std::uint16_t index; std::uint8_t subindex; std::uint8_t bits; }};
struct PdoDefault {{
  std::uint16_t number;            // 1-based PDO number
  std::uint32_t cob_id_base;       // e.g. 0x180 for TPDO1; actual COB-ID = base + node id
  bool enabled;
  std::uint8_t transmission_type;  // 1..240 synchronous every n-th SYNC, 254/255 event
  std::uint16_t inhibit_time_100us;
  std::uint16_t event_timer_ms;
  std::uint8_t count;              // used entries
  std::array<PdoMapEntry, {PDO_MAX_ENTRIES}> entries;
}};

inline constexpr std::size_t kRpdoCount = {len(table.rpdos)};  // RPDO slots (0x1400.., 0x1600..)
inline constexpr std::size_t kTpdoCount = {len(table.tpdos)};  // TPDO slots (0x1800.., 0x1A00..)

inline constexpr std::array<PdoDefault, kRpdoCount> kDefaultRpdos = {{{{
{rpdos}
}}}};
inline constexpr std::array<PdoDefault, kTpdoCount> kDefaultTpdos = {{{{
{tpdos}
}}}};

{_emcy_section(table)}
{_values_section(table)}
{_fault_flags_section(table)}
{"" if table.recorder is None else _recorder_section(table.recorder)}}}  // namespace board
"""
