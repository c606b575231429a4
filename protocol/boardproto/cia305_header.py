"""Generate `board/cia305.hpp`: the CiA 305 (LSS) rules of `boardproto.cia305` for the
firmware (namespace cia305), so that the LSS slave never writes a COB-ID, a command specifier or
an error code down by hand. Like `board/cia301.hpp` it depends on the Python module alone."""

from __future__ import annotations

from boardproto import cia305
from boardproto.cia301_header import _enumerators, _hex

GENERATED_BANNER = "// Generated from protocol/boardproto/cia305.py by protocol/boardproto. Do not edit."


def _bit_timing_rows() -> str:
    return "\n".join(f"    {{{index}, {kbits}}}," for index, kbits in cia305.BIT_TIMING_KBITS.items())


def generate_cia305_header() -> str:
    """The whole header; the same text for every board (it does not read the table)."""
    return f"""{GENERATED_BANNER}
// CiA 305 Layer Setting Services the firmware's LSS slave and the rig's LSS master share: the
// COB-IDs, command specifiers, states, answer error codes, fastscan values, bit timing table.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace cia305 {{

inline constexpr std::uint32_t kMasterCobId = {_hex(cia305.MASTER_COB_ID, 3)};  // master -> slaves
inline constexpr std::uint32_t kSlaveCobId = {_hex(cia305.SLAVE_COB_ID, 3)};   // slave -> master
inline constexpr std::size_t kFrameBytes = {cia305.FRAME_BYTES};
// The node id of a node that has none yet: LSS only, no boot-up, no NMT.
inline constexpr std::uint8_t kNodeIdUnconfigured = {_hex(cia305.NODE_ID_UNCONFIGURED, 2)};

enum class LssState : std::uint8_t {{
{_enumerators(list(cia305.LssState), 2)}
}};

enum class LssCommand : std::uint8_t {{
{_enumerators(list(cia305.LssCommand), 2)}
}};

// Byte 1 of the answers to configure node-id, configure bit timing and store configuration.
enum class LssError : std::uint8_t {{
{_enumerators(list(cia305.LssError), 2)}
}};

// Fastscan: bit-check 0..31, or this value to reset every non-configured slave's scan.
inline constexpr std::uint8_t kFastscanConfirm = {_hex(cia305.FASTSCAN_CONFIRM, 2)};
inline constexpr std::uint8_t kFastscanHighestBit = {cia305.FASTSCAN_HIGHEST_BIT};
// LSS sub / next: 0 vendor id, 1 product code, 2 revision, 3 serial number.
inline constexpr std::uint8_t kIdentityParts = {cia305.IDENTITY_PARTS};

// Configure bit timing: the CiA 301 table (selector 0), index -> kbit/s.
inline constexpr std::uint8_t kBitTimingStandardTable = {cia305.BIT_TIMING_STANDARD_TABLE};
struct BitTiming {{
  std::uint8_t index;
  std::uint16_t kbits;
}};
inline constexpr std::array<BitTiming, {len(cia305.BIT_TIMING_KBITS)}> kBitTimings = {{{{
{_bit_timing_rows()}
}}}};

// kbit/s of table index `index`; 0 when the table has no such entry.
constexpr std::uint16_t bit_timing_kbits(std::uint8_t index) {{
  for (const BitTiming& timing : kBitTimings) {{
    if (timing.index == index) return timing.kbits;
  }}
  return 0;
}}

}}  // namespace cia305
"""
