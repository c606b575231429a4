"""Generate `board/cia301.hpp`: the CiA 301 rules of `boardproto.cia301` for the firmware
(namespace cia301), so that the C++ side never writes an abort code, a COB-ID base, an NMT state
or the EMCY layout down by hand. The header depends on `cia301.py` alone, not on board.toml."""

from __future__ import annotations

import enum

from boardproto import cia301
from boardproto.cpp_header import cpp_string
from boardproto.table import camel_case

GENERATED_BANNER = "// Generated from protocol/boardproto/cia301.py by protocol/boardproto. Do not edit."


def cpp_name(member: enum.Enum) -> str:
    """PRE_OPERATIONAL -> PreOperational: the C++ enumerator of a Python enum member."""
    return camel_case(member.name.lower())


def _hex(value: int, digits: int) -> str:
    """0x0609'0031 style: C++ digit separators every 4 digits, as the spec tables group them."""
    text = f"{value:0{digits}X}"
    if digits > 4:
        text = f"{text[:-4]}'{text[-4:]}"
    return f"0x{text}"


def _enumerators(members: list[enum.IntEnum], digits: int) -> str:
    return "\n".join(f"  {cpp_name(m)} = {_hex(int(m), digits)}," for m in members)


def _sdo_abort_enumerators() -> str:
    lines = [f"  None = {_hex(0, 8)},  // not an abort: the access succeeded"]
    lines += [f"  {cpp_name(m)} = {_hex(int(m), 8)},  // {m.text}" for m in cia301.SdoAbortCode]
    return "\n".join(lines)


def _sdo_abort_infos() -> str:
    return "\n".join(f"    {{SdoAbort::{cpp_name(m)}, {cpp_string(m.text)}}}," for m in cia301.SdoAbortCode)


def _restricted_ranges() -> str:
    return "\n".join(
        f"    {{{_hex(first, 3)}, {_hex(last, 3)}}}," for first, last in cia301.RESTRICTED_COB_ID_RANGES
    )


def generate_cia301_header() -> str:
    """The whole header; the same text for every board (it does not read the table)."""
    layout = cia301.EmcyLayout
    return f"""{GENERATED_BANNER}
// CiA 301 rules the firmware and the rig share: the predefined connection set, node-id limits,
// NMT states and commands, the EMCY frame layout and the SDO abort codes with their texts.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string_view>

namespace cia301 {{

// ---------------------------------------------------------------------------
// Predefined connection set (CiA 301, 7.3.3): COB-ID = base + node id for per-node services.
// ---------------------------------------------------------------------------
enum class FunctionCode : std::uint16_t {{
{_enumerators(list(cia301.FunctionCode), 3)}
}};

inline constexpr std::uint32_t kNmtCobId = {_hex(cia301.NMT_COB_ID, 3)};
inline constexpr std::uint32_t kSyncCobId = {_hex(cia301.SYNC_COB_ID, 3)};  // the default of 0x1005
inline constexpr std::uint32_t kTimeCobId = {_hex(cia301.TIME_COB_ID, 3)};
inline constexpr std::uint32_t kStandardIdMask = {_hex(cia301.STANDARD_ID_MASK, 3)};
inline constexpr std::uint32_t kFunctionCodeMask = {_hex(cia301.FUNCTION_CODE_MASK, 3)};
inline constexpr std::uint32_t kNodeIdMask = {_hex(cia301.NODE_ID_MASK, 2)};
// PDO 5..8 of the common extension: the bases of PDO 1..4 plus this.
inline constexpr std::uint32_t kPdoExtensionOffset = {_hex(cia301.PDO_EXTENSION_OFFSET, 2)};

// The COB-ID of a per-node service of node `node_id`.
constexpr std::uint32_t cob_id(FunctionCode function, std::uint32_t node_id) {{
  return static_cast<std::uint32_t>(function) + node_id;
}}

// CAN identifiers reserved for NMT, SYNC/EMCY, TIME, SDO and error control (CiA 301, 7.3.5):
// no configurable COB-ID (a PDO's, SYNC's 0x1005) may use them. Inclusive ranges.
struct CobIdRange {{
  std::uint32_t first;
  std::uint32_t last;
}};
inline constexpr std::array<CobIdRange, {len(cia301.RESTRICTED_COB_ID_RANGES)}> kRestrictedCobIds = {{{{
{_restricted_ranges()}
}}}};

constexpr bool is_restricted_cob_id(std::uint32_t id) {{
  for (const CobIdRange& range : kRestrictedCobIds) {{
    if (id >= range.first && id <= range.last) return true;
  }}
  return false;
}}

// ---------------------------------------------------------------------------
// Node ids (CiA 301, 7.3.2); 0 in an NMT command addresses every node.
// ---------------------------------------------------------------------------
inline constexpr std::uint8_t kMinNodeId = {cia301.MIN_NODE_ID};
inline constexpr std::uint8_t kMaxNodeId = {cia301.MAX_NODE_ID};
inline constexpr std::uint8_t kNmtAllNodes = {cia301.NMT_ALL_NODES};

constexpr bool is_node_id(std::uint32_t node_id) {{ return node_id >= kMinNodeId && node_id <= kMaxNodeId; }}

// ---------------------------------------------------------------------------
// NMT (CiA 301, 7.2.8.3): the states are the heartbeat state bytes.
// ---------------------------------------------------------------------------
enum class NmtState : std::uint8_t {{
{_enumerators(list(cia301.NmtState), 2)}
}};

enum class NmtCommand : std::uint8_t {{
{_enumerators(list(cia301.NmtCommand), 2)}
}};

// The state bits of a heartbeat byte; the top bit is node guarding's toggle bit.
inline constexpr std::uint8_t kHeartbeatStateMask = {_hex(cia301.HEARTBEAT_STATE_MASK, 2)};
// Consumer heartbeat time: one UNSIGNED32 per watched node (sub-index 1..n).
inline constexpr std::uint16_t kHeartbeatConsumerIndex = {_hex(cia301.HEARTBEAT_CONSUMER_INDEX, 4)};
// Error behaviour: sub 1 says what a heartbeat event does to the NMT state (CiA 301, 7.5.2.32).
inline constexpr std::uint16_t kErrorBehaviourIndex = {_hex(cia301.ERROR_BEHAVIOUR_INDEX, 4)};

enum class ErrorBehaviour : std::uint8_t {{
{_enumerators(list(cia301.ErrorBehaviour), 2)}
}};

// ---------------------------------------------------------------------------
// SYNC and PDO transmission types (CiA 301, 7.2.5, 7.5.2.35).
// ---------------------------------------------------------------------------
inline constexpr std::uint8_t kSyncCounterMax = {cia301.SYNC_COUNTER_MAX};
inline constexpr std::uint8_t kLastSynchronousType = {cia301.LAST_SYNCHRONOUS_TYPE};

// ---------------------------------------------------------------------------
// EMCY frame layout (CiA 301, 7.2.7.3.1): error code (LE), error register, manufacturer bytes.
// ---------------------------------------------------------------------------
namespace emcy_layout {{
inline constexpr std::size_t kFrameBytes = {layout.FRAME_BYTES};
inline constexpr std::size_t kErrorCodeOffset = {layout.ERROR_CODE_OFFSET};
inline constexpr std::size_t kErrorCodeBytes = {layout.ERROR_CODE_BYTES};
inline constexpr std::size_t kErrorRegisterOffset = {layout.ERROR_REGISTER_OFFSET};
inline constexpr std::size_t kManufacturerOffset = {layout.MANUFACTURER_OFFSET};
inline constexpr std::size_t kManufacturerBytes = {layout.MANUFACTURER_BYTES};
}}  // namespace emcy_layout

// "Error reset or no error": sent when an error goes away.
inline constexpr std::uint16_t kEmcyErrorReset = {_hex(cia301.EMCY_ERROR_RESET, 4)};

// ---------------------------------------------------------------------------
// SDO abort codes (CiA 301, 7.2.4.3.17). The enumerator values ARE the codes on the wire.
// ---------------------------------------------------------------------------
enum class SdoAbort : std::uint32_t {{
{_sdo_abort_enumerators()}
}};

constexpr std::uint32_t to_code(SdoAbort abort) {{ return static_cast<std::uint32_t>(abort); }}

struct SdoAbortInfo {{
  SdoAbort abort;
  std::string_view text;
}};

// Every abort code with its text, in the order of the codes.
inline constexpr std::array<SdoAbortInfo, {len(cia301.SdoAbortCode)}> kSdoAborts = {{{{
{_sdo_abort_infos()}
}}}};

// The text of `abort`; "" for SdoAbort::None and for a value that is no abort code.
constexpr std::string_view text(SdoAbort abort) {{
  for (const SdoAbortInfo& info : kSdoAborts) {{
    if (info.abort == abort) return info.text;
  }}
  return {{}};
}}

}}  // namespace cia301
"""
