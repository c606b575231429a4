// Internal: little-endian coding and lookups over the generated tables in board/fields.hpp.
#pragma once

#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <span>

#include "board/cia301.hpp"
#include "board/fields.hpp"

namespace co::tables {

// Communication profile indices (CiA 301, 7.5).
inline constexpr std::uint16_t kRpdoCommunicationBase = 0x1400;
inline constexpr std::uint16_t kRpdoMappingBase = 0x1600;
inline constexpr std::uint16_t kTpdoCommunicationBase = 0x1800;
inline constexpr std::uint16_t kTpdoMappingBase = 0x1A00;

// PDO COB-ID bit 31: 1 = PDO not valid (CiA 301, 7.5.2.35/37).
inline constexpr std::uint32_t kPdoInvalidBit = 0x8000'0000u;

constexpr std::uint8_t size_of(board::DataType type) {
  switch (type) {
    case board::DataType::Boolean:
    case board::DataType::Integer8:
    case board::DataType::Unsigned8: return 1;
    case board::DataType::Integer16:
    case board::DataType::Unsigned16: return 2;
    case board::DataType::Integer32:
    case board::DataType::Unsigned32:
    case board::DataType::Real32: return 4;
    case board::DataType::VisibleString:
    case board::DataType::Domain: return 0;  // sized by the object, not the type
  }
  return 0;
}

constexpr bool is_signed(board::DataType type) {
  return type == board::DataType::Integer8 || type == board::DataType::Integer16 ||
         type == board::DataType::Integer32;
}

// Little endian, `bytes.size()` (1..4) bytes.
inline std::uint32_t get_le(std::span<const std::uint8_t> bytes) {
  std::uint32_t v = 0;
  for (std::size_t i = 0; i < bytes.size() && i < 4; ++i) v |= std::uint32_t{bytes[i]} << (8 * i);
  return v;
}
inline void put_le(std::span<std::uint8_t> bytes, std::uint32_t v) {
  for (std::size_t i = 0; i < bytes.size() && i < 4; ++i) {
    bytes[i] = static_cast<std::uint8_t>(v >> (8 * i));
  }
}

// The integer an object of `type` holds when its bytes read `raw`.
constexpr std::int64_t integer_value(board::DataType type, std::uint32_t raw) {
  switch (type) {
    case board::DataType::Integer8: return static_cast<std::int8_t>(raw & 0xFF);
    case board::DataType::Integer16: return static_cast<std::int16_t>(raw & 0xFFFF);
    case board::DataType::Integer32: return static_cast<std::int32_t>(raw);
    case board::DataType::Boolean:
    case board::DataType::Unsigned8: return raw & 0xFF;
    case board::DataType::Unsigned16: return raw & 0xFFFF;
    default: return raw;
  }
}

// A board field's value as its object's bytes (`size_of(field.type)` of them): a REAL32's bits,
// or a device profile object's integer (the table keeps its range exact in a float).
inline std::uint32_t field_raw(const board::FieldInfo& field, float value) {
  if (field.type == board::DataType::Real32) return std::bit_cast<std::uint32_t>(value);
  return static_cast<std::uint32_t>(static_cast<std::int32_t>(std::lround(value)));
}

// The board value of a field whose object's bytes read `raw`.
inline float field_value(const board::FieldInfo& field, std::uint32_t raw) {
  if (field.type == board::DataType::Real32) return std::bit_cast<float>(raw);
  return static_cast<float>(integer_value(field.type, raw));
}

// The field at (index, sub): sub 0 for a plain object, 1..n for an ARRAY's member.
constexpr std::optional<board::FieldId> field_at(std::uint16_t index, std::uint8_t sub = 0) {
  for (std::size_t i = 0; i < board::kFieldCount; ++i) {
    if (board::kFields[i].index == index && board::kFields[i].subindex == sub) return static_cast<board::FieldId>(i);
  }
  return std::nullopt;
}

// The ARRAY of board fields at `index`, if the object is one.
constexpr const board::FieldArrayInfo* field_array_at(std::uint16_t index) {
  for (const board::FieldArrayInfo& array : board::kFieldArrays) {
    if (array.index == index) return &array;
  }
  return nullptr;
}

constexpr std::optional<board::HilInputId> hil_input_at(std::uint16_t index) {
  for (std::size_t i = 0; i < board::kHilInputs.size(); ++i) {
    if (board::kHilInputs[i].index == index) return static_cast<board::HilInputId>(i);
  }
  return std::nullopt;
}

constexpr std::optional<board::HilOutputId> hil_output_at(std::uint16_t index) {
  for (std::size_t i = 0; i < board::kHilOutputs.size(); ++i) {
    if (board::kHilOutputs[i].index == index) return static_cast<board::HilOutputId>(i);
  }
  return std::nullopt;
}

// HilIo carries int32: every declared input range must fit.
constexpr bool hil_inputs_fit_int32() {
  for (const board::IoInfo& io : board::kHilInputs) {
    if (io.min < std::numeric_limits<std::int32_t>::min() ||
        io.max > std::numeric_limits<std::int32_t>::max() || size_of(io.type) == 0) {
      return false;
    }
  }
  for (const board::IoInfo& io : board::kHilOutputs) {
    if (size_of(io.type) == 0) return false;
  }
  return true;
}

}  // namespace co::tables
