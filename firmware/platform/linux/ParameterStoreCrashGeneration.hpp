// The parameter sets the store-crash test writes (ParameterStoreCrashChild.cpp) and checks
// (FileParameterStorageCrashTest.cpp): generation `g` gives every stored field one value derived
// from `g`, so a loaded set is either exactly one generation or provably torn/mixed, whatever
// the image CRC says. Test-only.
//
// Two integer-valued parameters carry the generation itself (low and high 16 bits, stored as
// 1 + bits, exact in a float); every other stored field gets a value spread over its range.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>

#include "board/fields.hpp"

namespace linuxhw::store_crash {

inline constexpr board::FieldId kGenerationLow = board::FieldId::encoder_counts_per_rev;
inline constexpr board::FieldId kGenerationHigh = board::FieldId::output_encoder_counts_per_rev;

namespace detail {
constexpr bool carries_16_bits(board::FieldId id) {
  const board::FieldInfo& field = board::info(id);
  return field.stored && field.access == board::Access::ReadWrite && field.min <= 1.0f &&
         field.max >= 65536.0f;
}
}  // namespace detail
static_assert(detail::carries_16_bits(kGenerationLow) && detail::carries_16_bits(kGenerationHigh),
              "the generation carriers must be stored, writable and hold 1..65536: pick others");

// Value of stored field `id` in generation `generation`; always inside the field's range.
inline float value_in_generation(board::FieldId id, std::uint32_t generation) {
  if (id == kGenerationLow) return static_cast<float>(1 + (generation & 0xFFFFu));
  if (id == kGenerationHigh) return static_cast<float>(1 + (generation >> 16));
  const board::FieldInfo& field = board::info(id);
  // A different, scrambled fraction in [0, 1) per field and generation.
  const std::uint32_t mix = (generation * 2'654'435'761u) ^ (static_cast<std::uint32_t>(id) * 40'503u);
  const double fraction = static_cast<double>((mix >> 8) % 4096u) / 4096.0;
  const double value = field.min + (static_cast<double>(field.max) - field.min) * fraction;
  return static_cast<float>(value) > field.max ? field.max : static_cast<float>(value);
}

// The generation the carriers name; nullopt when they are not integers in 1..65536.
inline std::optional<std::uint32_t> generation_of(float low, float high) {
  const auto bits = [](float v) -> std::optional<std::uint32_t> {
    if (!(v >= 1.0f && v <= 65536.0f) || std::floor(v) != v) return std::nullopt;
    return static_cast<std::uint32_t>(v) - 1;
  };
  const auto lo = bits(low);
  const auto hi = bits(high);
  if (!lo || !hi) return std::nullopt;
  return (*hi << 16) | *lo;
}

}  // namespace linuxhw::store_crash
