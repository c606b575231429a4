"""Generate `board/cia402.hpp`: the CiA 402 rules of `boardproto.cia402` for the firmware
(namespace cia402): the drive states with their statusword patterns and masks, the controlword
and statusword bit numbers. Like `board/cia301.hpp` it depends on the Python module alone."""

from __future__ import annotations

from boardproto import cia402
from boardproto.cia301_header import _enumerators, _hex, cpp_name

GENERATED_BANNER = "// Generated from protocol/boardproto/cia402.py by protocol/boardproto. Do not edit."


def _masks() -> str:
    return "\n".join(
        f"    case State::{cpp_name(state)}: return {_hex(state.mask, 2)};" for state in cia402.State
    )


def generate_cia402_header() -> str:
    """The whole header; the same text for every board (it does not read the table)."""
    return f"""{GENERATED_BANNER}
// CiA 402 drive profile: the state machine's states as the statusword shows them, the
// controlword's and the statusword's bits.
#pragma once

#include <cstdint>

namespace cia402 {{

// The profile's number, in the lower 16 bits of a drive's device type (0x1000).
inline constexpr std::uint16_t kDeviceProfile = {cia402.DEVICE_PROFILE};

// The value is the state's statusword pattern under mask(state).
enum class State : std::uint16_t {{
{_enumerators(list(cia402.State), 2)}
}};

constexpr std::uint16_t mask(State state) {{
  switch (state) {{
{_masks()}
  }}
  return 0;
}}

// Controlword (0x6040) bit numbers.
enum class ControlBit : std::uint8_t {{
{_enumerators(list(cia402.ControlBit), 2)}
}};

// Statusword (0x6041) bit numbers besides the state's.
enum class StatusBit : std::uint8_t {{
{_enumerators(list(cia402.StatusBit), 2)}
}};

constexpr std::uint16_t bit(ControlBit b) {{
  return static_cast<std::uint16_t>(1u << static_cast<unsigned>(b));
}}
constexpr std::uint16_t bit(StatusBit b) {{
  return static_cast<std::uint16_t>(1u << static_cast<unsigned>(b));
}}

}}  // namespace cia402
"""
