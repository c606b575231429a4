"""The CiA 301 rules the firmware and the rig both follow: the predefined connection set
(function codes, COB-ID bases), node-id limits, NMT states and commands (the heartbeat byte),
the EMCY frame layout, the SDO abort codes with their texts, the SYNC counter and the rule for
which synchronous TPDO is due at which SYNC.

One home: the rig imports this module, and the firmware includes `board/cia301.hpp`, which
`boardproto.cia301_header` generates from it. Nothing else writes these numbers down.

    cob_id(FunctionCode.TPDO1, 0x10)      # 0x190
    due_at_sync(10, 20)                   # True: a type-10 TPDO goes out at every 10th SYNC
    SdoAbortCode(0x06090031).text         # 'value too high'
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Self


class FunctionCode(enum.IntEnum):
    """COB-ID base of each service (the 4-bit function code shifted into an 11-bit id); the
    node id is added for the per-node services (CiA 301, predefined connection set)."""

    NMT = 0x000
    SYNC_EMCY = 0x080  # SYNC alone; EMCY + node id (1..127)
    TIME = 0x100
    TPDO1 = 0x180
    RPDO1 = 0x200
    TPDO2 = 0x280
    RPDO2 = 0x300
    TPDO3 = 0x380
    RPDO3 = 0x400
    TPDO4 = 0x480
    RPDO4 = 0x500
    SDO_RESPONSE = 0x580  # server -> client
    SDO_REQUEST = 0x600  # client -> server
    HEARTBEAT = 0x700  # also node guarding and the boot-up message


NODE_ID_MASK = 0x7F
MIN_NODE_ID = 1
MAX_NODE_ID = 0x7F
"""Node ids 1..127 (CiA 301 7.3.2): 0 is NMT's "all nodes", never a node's own id."""
NMT_ALL_NODES = 0
"""The node id byte of an NMT command addressed to every node."""
FUNCTION_CODE_MASK = 0x780
STANDARD_ID_MASK = 0x7FF
TPDO_FUNCTIONS = (FunctionCode.TPDO1, FunctionCode.TPDO2, FunctionCode.TPDO3, FunctionCode.TPDO4)
RPDO_FUNCTIONS = (FunctionCode.RPDO1, FunctionCode.RPDO2, FunctionCode.RPDO3, FunctionCode.RPDO4)
SYNC_COB_ID = int(FunctionCode.SYNC_EMCY)
NMT_COB_ID = int(FunctionCode.NMT)
TIME_COB_ID = int(FunctionCode.TIME)
RESTRICTED_COB_ID_RANGES: tuple[tuple[int, int], ...] = (
    (0x000, 0x07F),  # NMT, and the ids below SYNC
    (0x101, 0x180),  # above TIME up to TPDO1's base
    (0x581, 0x5FF),  # SDO responses
    (0x601, 0x67F),  # SDO requests
    (0x6E0, 0x6FF),  # reserved
    (0x701, 0x7FF),  # error control (heartbeat, boot-up) and above
)
"""CAN identifiers CiA 301 (7.3.5) reserves for NMT, SYNC/EMCY, SDO and error control, as
inclusive ranges: no configurable COB-ID (a PDO's, SYNC's 0x1005) may use them."""


def is_restricted_cob_id(can_id: int) -> bool:
    """True when a configurable COB-ID may not take this 11-bit identifier."""
    return any(first <= can_id <= last for first, last in RESTRICTED_COB_ID_RANGES)


SYNC_COUNTER_MAX = 240
"""SYNC counters run 1..240 and wrap (CiA 301 counter overflow value 240)."""
LAST_SYNCHRONOUS_TYPE = 240
"""PDO transmission types 1..240: synchronous, every n-th SYNC; 0: acyclic synchronous;
254/255: event-driven."""
EVENT_DRIVEN_TYPES = (254, 255)
"""Event-driven transmission types: 254 manufacturer-specific, 255 device profile."""


HEARTBEAT_STATE_MASK = 0x7F
"""The state bits of a heartbeat (or node guarding) byte: the top bit is node guarding's toggle
bit, never part of the state."""


class NmtState(enum.IntEnum):
    """NMT states; the values are the heartbeat state bytes (CiA 301)."""

    INITIALISING = 0x00  # the boot-up message carries this
    STOPPED = 0x04
    OPERATIONAL = 0x05
    PRE_OPERATIONAL = 0x7F


class NmtCommand(enum.IntEnum):
    """NMT command specifiers (first byte of the frame on COB-ID 0)."""

    START = 0x01
    STOP = 0x02
    ENTER_PRE_OPERATIONAL = 0x80
    RESET_NODE = 0x81
    RESET_COMMUNICATION = 0x82

    @property
    def resulting_state(self) -> NmtState:
        """The state the node is in after this command (resets end in pre-operational)."""
        return {
            NmtCommand.START: NmtState.OPERATIONAL,
            NmtCommand.STOP: NmtState.STOPPED,
        }.get(self, NmtState.PRE_OPERATIONAL)


class SdoCommand(enum.IntEnum):
    """First byte of an SDO frame (the command specifier in its top 3 bits) for the frames the rig
    builds or recognises by hand; canopen's SDO client does the rest."""

    INITIATE_DOWNLOAD_REQUEST = 0x20  # ccs 1; the low bits say expedited / size indicated
    INITIATE_UPLOAD_REQUEST = 0x40  # ccs 2
    INITIATE_DOWNLOAD_RESPONSE = 0x60  # scs 3
    ABORT = 0x80  # cs 4, both directions


class SdoAbortCode(enum.IntEnum):
    """SDO abort codes (CiA 301, 7.2.4.3.17); the values ARE the codes on the wire, and each
    carries its text (`SdoAbortCode.VALUE_TOO_HIGH.text`: 'value too high'), which the rig
    prints and the generated C++ header holds beside the code."""

    text: str

    def __new__(cls, code: int, text: str) -> Self:
        member = int.__new__(cls, code)
        member._value_ = code
        member.text = text
        return member

    TOGGLE_BIT_NOT_ALTERNATED = 0x0503_0000, "toggle bit not alternated"
    PROTOCOL_TIMED_OUT = 0x0504_0000, "SDO protocol timed out"
    COMMAND_SPECIFIER_INVALID = (
        0x0504_0001,
        "command not valid (undefined, or out of turn in the transfer)",
    )
    INVALID_BLOCK_SIZE = 0x0504_0002, "block transfer: block size 0 or above 127"
    INVALID_SEQUENCE_NUMBER = 0x0504_0003, "block transfer: invalid sequence number"
    CRC_ERROR = 0x0504_0004, "block transfer: CRC does not match the data"
    OUT_OF_MEMORY = 0x0504_0005, "value larger than the node can buffer"
    UNSUPPORTED_ACCESS = 0x0601_0000, "unsupported access"
    WRITE_ONLY = 0x0601_0001, "object is write-only"
    READ_ONLY = 0x0601_0002, "object is read-only over the bus"
    OBJECT_DOES_NOT_EXIST = 0x0602_0000, "no such object in the node's dictionary"
    OBJECT_CANNOT_BE_MAPPED = 0x0604_0041, "object cannot be mapped to a PDO"
    PDO_LENGTH_EXCEEDED = 0x0604_0042, "mapping exceeds the 64 bits of a PDO"
    PARAMETER_INCOMPATIBLE = (
        0x0604_0043,
        "settings that do not fit together (a recorder without channels...)",
    )
    HARDWARE_ERROR = 0x0606_0000, "access failed: hardware error (e.g. writing the staged image)"
    LENGTH_MISMATCH = 0x0607_0010, "data length does not match the object's type"
    LENGTH_TOO_HIGH = 0x0607_0012, "data longer than the object's type"
    LENGTH_TOO_LOW = 0x0607_0013, "data shorter than the object's type"
    SUB_INDEX_DOES_NOT_EXIST = 0x0609_0011, "no such sub-index"
    VALUE_RANGE_EXCEEDED = 0x0609_0030, "value out of range"
    VALUE_TOO_HIGH = 0x0609_0031, "value too high"
    VALUE_TOO_LOW = 0x0609_0032, "value too low"
    RESOURCE_NOT_AVAILABLE = 0x060A_0023, "resource not available"
    GENERAL_ERROR = 0x0800_0000, "general error"
    DATA_CANNOT_BE_STORED = 0x0800_0020, "refused by the application (or storage failed)"
    LOCAL_CONTROL = 0x0800_0021, "refused: under local control"
    DEVICE_STATE = (
        0x0800_0022,
        "not possible in the node's present state (e.g. PDO change while operational)",
    )


class EmcyLayout:
    """Where the parts of an EMCY frame go (CiA 301, 7.2.7.3.1): the error code (UNSIGNED16,
    little-endian) in bytes 0..1, the error register (0x1001) in byte 2, the manufacturer-specific
    error field in bytes 3..7. Every EMCY frame carries all 8 bytes."""

    FRAME_BYTES = 8
    ERROR_CODE_OFFSET = 0
    ERROR_CODE_BYTES = 2
    ERROR_REGISTER_OFFSET = 2
    MANUFACTURER_OFFSET = 3
    MANUFACTURER_BYTES = 5


EMCY_ERROR_RESET = 0x0000
"""The EMCY error code of 'error reset or no error': sent when an error goes away, with the error
register that remains."""


@dataclass(frozen=True)
class EmcyFrame:
    """The three parts of an EMCY frame's data."""

    code: int
    register: int
    manufacturer: bytes


def split_emcy(data: bytes) -> EmcyFrame:
    """The parts of an EMCY frame's data; a short frame (a node that breaks the layout) gives
    what it has: missing bytes read as 0 / empty."""
    code = int.from_bytes(data[EmcyLayout.ERROR_CODE_OFFSET : EmcyLayout.ERROR_CODE_BYTES], "little")
    register = data[EmcyLayout.ERROR_REGISTER_OFFSET] if len(data) > EmcyLayout.ERROR_REGISTER_OFFSET else 0
    manufacturer = bytes(
        data[EmcyLayout.MANUFACTURER_OFFSET : EmcyLayout.MANUFACTURER_OFFSET + EmcyLayout.MANUFACTURER_BYTES]
    )
    return EmcyFrame(code, register, manufacturer)


def function_of(cob_id: int) -> tuple[int, int]:
    """(function code bits, node id) of an 11-bit COB-ID: 0x190 -> (0x180, 0x10)."""
    return cob_id & FUNCTION_CODE_MASK, cob_id & NODE_ID_MASK


def is_node_id(node_id: int) -> bool:
    """True for a node's own id, 1..127."""
    return MIN_NODE_ID <= node_id <= MAX_NODE_ID


def cob_id(function: FunctionCode, node_id: int) -> int:
    """The COB-ID of a per-node service: base + node id."""
    if not is_node_id(node_id):
        raise ValueError(f"node id: expected {MIN_NODE_ID}..{MAX_NODE_ID}, got {node_id}")
    return int(function) + node_id


PDO_EXTENSION_OFFSET = 0x40
"""PDO 5..8 by the common extension of the predefined set: PDO 1..4's bases + 0x40 (so they share
identifiers with PDO 1..4 of node id + 64)."""
MAX_NODE_ID_WITH_PDO_5_TO_8 = PDO_EXTENSION_OFFSET - 1
"""The highest node id (63) whose PDO 5..8 identifiers are no other node's PDO 1..4: nodes that
use 8 PDOs each share a bus only with ids 1..63."""


def predefined_pdo_base(functions: tuple[FunctionCode, ...], number: int) -> int | None:
    """COB-ID base of PDO `number` (1-based) of one direction (`TPDO_FUNCTIONS` or
    `RPDO_FUNCTIONS`): 1..4 from the predefined connection set, 5..8 the same + 0x40; None beyond
    (there is no standard default after PDO 4)."""
    if not 1 <= number <= 2 * len(functions):
        return None
    block, step = divmod(number - 1, len(functions))
    return int(functions[step]) + PDO_EXTENSION_OFFSET * block


def emcy_cob_id(node_id: int) -> int:
    return cob_id(FunctionCode.SYNC_EMCY, node_id)


def heartbeat_cob_id(node_id: int) -> int:
    return cob_id(FunctionCode.HEARTBEAT, node_id)


MASTER_NODE_ID = 0x7F
"""The node id of the rig's own heartbeat as the bus master (CiA 301 leaves it to the system:
127, the highest, stays clear of a robot's modules 1..63)."""
MASTER_HEARTBEAT_MS = 20
"""How often the rig as master sends its heartbeat by default (a robot's modules watch it)."""

HEARTBEAT_CONSUMER_INDEX = 0x1016
"""Consumer heartbeat time: one UNSIGNED32 per watched node (sub-index 1..n)."""


STORE_PARAMETERS_INDEX = 0x1010
"""Store parameters: sub 1 all, 2 communication, 3 application; written with STORE_SIGNATURE."""
STORE_COMMUNICATION = 2
STORE_SIGNATURE = int.from_bytes(b"save", "little")
"""What a write to 0x1010 must carry (CiA 301 7.5.2.13: the ASCII "save", little-endian)."""
SYNC_COUNTER_OVERFLOW_INDEX = 0x1019
"""Synchronous counter overflow value: 0 = SYNC without counter, 2..240 the counter's period."""

ERROR_BEHAVIOUR_INDEX = 0x1029
"""Error behaviour: sub 1 (UNSIGNED8) says what a communication error (a heartbeat event of 0x1016)
does to the NMT state; absent or 0 means pre-operational (CiA 301 7.5.2.32)."""


class ErrorBehaviour(enum.IntEnum):
    """Values of 0x1029 sub 1 (CiA 301 7.5.2.32); 3..127 are reserved."""

    PRE_OPERATIONAL = 0  # enter pre-operational, if operational (the default)
    NO_CHANGE = 1  # the NMT state stays
    STOPPED = 2  # enter stopped


def heartbeat_consumer_entry(node_id: int, time_ms: int) -> int:
    """One 0x1016 entry: the node id to watch in bits 16..23, its consumer time [ms] in bits
    0..15 (CiA 301 7.5.2.31); a heartbeat later than that from the node is a heartbeat event."""
    if not is_node_id(node_id):
        raise ValueError(f"heartbeat consumer: node id {MIN_NODE_ID}..{MAX_NODE_ID} expected, got {node_id}")
    if not 1 <= time_ms <= 0xFFFF:
        raise ValueError(f"heartbeat consumer: time 1..65535 ms expected, got {time_ms}")
    return node_id << 16 | time_ms


def sdo_response_cob_id(node_id: int) -> int:
    return cob_id(FunctionCode.SDO_RESPONSE, node_id)


def sdo_request_cob_id(node_id: int) -> int:
    return cob_id(FunctionCode.SDO_REQUEST, node_id)


def sync_counter(cycle: int) -> int:
    """The SYNC counter of cycle index `cycle` (0-based): 1..240, wrapping."""
    return cycle % SYNC_COUNTER_MAX + 1


def due_at_sync(transmission_type: int, sync_number: int) -> bool:
    """True when a cyclic synchronous TPDO (type n = 1..240) is sent at this SYNC.

    sync_number counts SYNCs since the node entered operational (1 = first): the node counts
    SYNCs per PDO from that moment and sends at every n-th. Type 0 (acyclic, only on change)
    and event-driven types are never *due*.
    """
    n = transmission_type
    return 1 <= n <= LAST_SYNCHRONOUS_TYPE and sync_number % n == 0


def transmission_text(transmission_type: int) -> str:
    """When a PDO of this transmission type goes out, in words: 'every SYNC', 'every 10th SYNC',
    'acyclic synchronous', 'event-driven', 'reserved type 245'."""
    n = transmission_type
    if n == 1:
        return "every SYNC"
    if 2 <= n <= LAST_SYNCHRONOUS_TYPE:
        return f"every {n}th SYNC"
    if n == 0:
        return "acyclic synchronous"
    if n in EVENT_DRIVEN_TYPES:
        return "event-driven"
    return f"reserved type {n}"


__all__ = [
    "EMCY_ERROR_RESET",
    "ERROR_BEHAVIOUR_INDEX",
    "EVENT_DRIVEN_TYPES",
    "FUNCTION_CODE_MASK",
    "HEARTBEAT_CONSUMER_INDEX",
    "HEARTBEAT_STATE_MASK",
    "LAST_SYNCHRONOUS_TYPE",
    "MASTER_HEARTBEAT_MS",
    "MASTER_NODE_ID",
    "MAX_NODE_ID",
    "MAX_NODE_ID_WITH_PDO_5_TO_8",
    "MIN_NODE_ID",
    "NMT_ALL_NODES",
    "NMT_COB_ID",
    "NODE_ID_MASK",
    "PDO_EXTENSION_OFFSET",
    "RESTRICTED_COB_ID_RANGES",
    "RPDO_FUNCTIONS",
    "STANDARD_ID_MASK",
    "STORE_COMMUNICATION",
    "STORE_PARAMETERS_INDEX",
    "STORE_SIGNATURE",
    "SYNC_COB_ID",
    "SYNC_COUNTER_MAX",
    "SYNC_COUNTER_OVERFLOW_INDEX",
    "TIME_COB_ID",
    "TPDO_FUNCTIONS",
    "EmcyFrame",
    "EmcyLayout",
    "ErrorBehaviour",
    "FunctionCode",
    "NmtCommand",
    "NmtState",
    "SdoAbortCode",
    "SdoCommand",
    "cob_id",
    "due_at_sync",
    "emcy_cob_id",
    "function_of",
    "heartbeat_cob_id",
    "heartbeat_consumer_entry",
    "is_node_id",
    "is_restricted_cob_id",
    "predefined_pdo_base",
    "sdo_request_cob_id",
    "sdo_response_cob_id",
    "split_emcy",
    "sync_counter",
    "transmission_text",
]
