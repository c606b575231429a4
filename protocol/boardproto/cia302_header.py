"""Generate `board/cia302.hpp`: the CiA 302-3 (program download) rules of `boardproto.cia302`
for the firmware (namespace cia302): object indices, program control values, the flash status
layout and the image header's layout, so the firmware's program download writes none of them
down by hand. Like `board/cia301.hpp` it depends on the Python module alone."""

from __future__ import annotations

from boardproto import cia302
from boardproto.cia301_header import _enumerators, _hex, cpp_name

GENERATED_BANNER = "// Generated from protocol/boardproto/cia302.py by protocol/boardproto. Do not edit."


def _magic_bytes() -> str:
    return ", ".join(f"0x{byte:02X}" for byte in cia302.IMAGE_MAGIC)


def _image_fields() -> str:
    return "\n".join(f"inline constexpr std::size_t k{cpp_name(f)} = {int(f)};" for f in cia302.ImageField)


def generate_cia302_header() -> str:
    """The whole header; the same text for every board (it does not read the table)."""
    return f"""{GENERATED_BANNER}
// CiA 302-3 program download the firmware and `hilrig flash` share: the objects 0x1F50/51/56/57,
// the program control commands, the flash status (0x1F57) and the firmware image header.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace cia302 {{

// DOMAIN wo, UNSIGNED8 rw, UNSIGNED32 ro, UNSIGNED32 ro.
inline constexpr std::uint16_t kProgramDataIndex = {_hex(cia302.PROGRAM_DATA_INDEX, 4)};
inline constexpr std::uint16_t kProgramControlIndex = {_hex(cia302.PROGRAM_CONTROL_INDEX, 4)};
inline constexpr std::uint16_t kSoftwareIdIndex = {_hex(cia302.SOFTWARE_ID_INDEX, 4)};
inline constexpr std::uint16_t kFlashStatusIndex = {_hex(cia302.FLASH_STATUS_INDEX, 4)};
inline constexpr std::uint8_t kProgramNumber = {cia302.PROGRAM_NUMBER};  // the sub-index of each

// 0x1F51 values.
enum class ProgramControl : std::uint8_t {{
{_enumerators(list(cia302.ProgramControl), 2)}
}};

// 0x1F57 bits 1..7 (CiA 302-3 1..7, manufacturer-specific 64..127); bit 0: in progress.
enum class FlashError : std::uint8_t {{
{_enumerators(list(cia302.FlashError), 2)}
}};
inline constexpr std::uint32_t kFlashInProgressBit = {_hex(cia302.FLASH_IN_PROGRESS_BIT, 2)};
inline constexpr unsigned kFlashErrorShift = {cia302.FLASH_ERROR_SHIFT};

constexpr std::uint32_t flash_status(FlashError error, bool in_progress) {{
  return (static_cast<std::uint32_t>(error) << kFlashErrorShift) | (in_progress ? kFlashInProgressBit : 0u);
}}

// The image header (little-endian); a firmware image is this header, then the payload.
inline constexpr std::array<std::uint8_t, {len(cia302.IMAGE_MAGIC)}> kImageMagic = {{{_magic_bytes()}}};
inline constexpr std::uint16_t kImageFormatVersion = {cia302.IMAGE_FORMAT_VERSION};
inline constexpr std::size_t kImageHeaderBytes = {cia302.IMAGE_HEADER_BYTES};
inline constexpr std::size_t kImageVersionBytes = {cia302.IMAGE_VERSION_BYTES};
// A macro, not a constant: __attribute__((section(...))) takes a string literal only.
#define HIL_SOFTWARE_VERSION_SECTION "{cia302.SOFTWARE_VERSION_SECTION}"
namespace image_field {{
{_image_fields()}
}}  // namespace image_field

}}  // namespace cia302
"""
