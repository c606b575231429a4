"""Generate `board/fields.hpp`: the firmware's view of the board table (namespace board)."""

from __future__ import annotations

from boardproto.table import BoardTable, DataType, Field, HilIo, Pdo

GENERATED_BANNER = "// Generated from protocol/board.toml by protocol/boardproto. Do not edit."
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
        f".unit = {cpp_string(field.unit)},\n"
        f"     .kind = Kind::{field.kind.cpp_name}, .access = Access::{field.access.cpp_name},\n"
        f"     .min = {cpp_float(field.min)}, .max = {cpp_float(field.max)}, "
        f".default_value = {cpp_float(field.default)}, "
        f".stored = {'true' if field.stored else 'false'},\n"
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


def generate_header(table: BoardTable) -> str:
    """The whole header text. Deterministic: same table, same bytes."""
    node = table.node
    field_ids = _enumerators(
        [f.name for f in table.fields],
        [f"0x{f.index:04X} [{f.unit}] {f.kind.value}, {f.access.value}" for f in table.fields],
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
    inputs = "\n".join(_io_initializer(io) for io in table.hil_inputs)
    outputs = "\n".join(_io_initializer(io) for io in table.hil_outputs)
    rpdos = "\n".join(_pdo_initializer(p) for p in table.rpdos)
    tpdos = "\n".join(_pdo_initializer(p) for p in table.tpdos)

    return f"""{GENERATED_BANNER}
// Board fields, hardware-in-the-loop I/O objects, node identity and default PDOs.
// Edit protocol/board.toml and rebuild; the EDS and DBC beside this header come from
// the same table.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string_view>

namespace board {{

// ---------------------------------------------------------------------------
// Board fields. Every field is a REAL32 object at (index, sub-index 0).
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
  std::uint16_t index;          // object index (sub-index is always 0), 0x2000..0x5FFF
  std::string_view unit;        // "rad", "rad/s", "N*m", "degC", "ohm", "1" ...
  Kind kind;
  Access access;
  float min, max, default_value;
  bool stored;                  // saved by 0x1010 "store parameters"
  std::string_view description;
}};

inline constexpr std::array<FieldInfo, kFieldCount> kFields = {{{{
{fields}
}}}};

constexpr const FieldInfo& info(FieldId id) {{ return kFields[static_cast<std::size_t>(id)]; }}

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
// Node identity (0x1000, 0x1008..0x100A, 0x1017, 0x1018).
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
}};

// Number of entries of 0x1003 "pre-defined error field" (sub-indices 1..n).
inline constexpr std::size_t kErrorHistoryLength = {node.error_history_length};

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

}}  // namespace board
"""
