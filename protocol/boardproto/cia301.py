"""The CiA 301 predefined connection set: function codes, COB-ID bases, the SYNC counter and
the rule for which synchronous TPDO is due at which SYNC. One home; everything else imports it.

    cob_id(FunctionCode.TPDO1, 0x10)      # 0x190
    due_at_sync(10, 20)                   # True: a type-10 TPDO goes out at every 10th SYNC
"""

from __future__ import annotations

import enum


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
FUNCTION_CODE_MASK = 0x780
STANDARD_ID_MASK = 0x7FF
TPDO_FUNCTIONS = (FunctionCode.TPDO1, FunctionCode.TPDO2, FunctionCode.TPDO3, FunctionCode.TPDO4)
RPDO_FUNCTIONS = (FunctionCode.RPDO1, FunctionCode.RPDO2, FunctionCode.RPDO3, FunctionCode.RPDO4)
SYNC_COB_ID = int(FunctionCode.SYNC_EMCY)
NMT_COB_ID = int(FunctionCode.NMT)
TIME_COB_ID = int(FunctionCode.TIME)
SYNC_COUNTER_MAX = 240
"""SYNC counters run 1..240 and wrap (CiA 301 counter overflow value 240)."""
LAST_SYNCHRONOUS_TYPE = 240
"""PDO transmission types 1..240: synchronous, every n-th SYNC; 0: acyclic synchronous;
254/255: event-driven."""
EVENT_DRIVEN_TYPES = (254, 255)
"""Event-driven transmission types: 254 manufacturer-specific, 255 device profile."""


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


def function_of(cob_id: int) -> tuple[int, int]:
    """(function code bits, node id) of an 11-bit COB-ID: 0x190 -> (0x180, 0x10)."""
    return cob_id & FUNCTION_CODE_MASK, cob_id & NODE_ID_MASK


def cob_id(function: FunctionCode, node_id: int) -> int:
    """The COB-ID of a per-node service: base + node id."""
    if not 1 <= node_id <= NODE_ID_MASK:
        raise ValueError(f"node id: expected 1..127, got {node_id}")
    return int(function) + node_id


PDO_EXTENSION_OFFSET = 0x40
"""PDO 5..8 by the common extension of the predefined set: PDO 1..4's bases + 0x40 (so they share
identifiers with PDO 1..4 of node id + 64)."""


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


def heartbeat_consumer_entry(node_id: int, time_ms: int) -> int:
    """One 0x1016 entry: the node id to watch in bits 16..23, its consumer time [ms] in bits
    0..15 (CiA 301 7.5.2.31); a heartbeat later than that from the node is a heartbeat event."""
    if not 1 <= node_id <= NODE_ID_MASK:
        raise ValueError(f"heartbeat consumer: node id 1..127 expected, got {node_id}")
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
    "EVENT_DRIVEN_TYPES",
    "FUNCTION_CODE_MASK",
    "HEARTBEAT_CONSUMER_INDEX",
    "LAST_SYNCHRONOUS_TYPE",
    "MASTER_HEARTBEAT_MS",
    "MASTER_NODE_ID",
    "NMT_COB_ID",
    "NODE_ID_MASK",
    "PDO_EXTENSION_OFFSET",
    "RPDO_FUNCTIONS",
    "STANDARD_ID_MASK",
    "SYNC_COB_ID",
    "SYNC_COUNTER_MAX",
    "TIME_COB_ID",
    "TPDO_FUNCTIONS",
    "FunctionCode",
    "NmtCommand",
    "NmtState",
    "SdoCommand",
    "cob_id",
    "due_at_sync",
    "emcy_cob_id",
    "function_of",
    "heartbeat_cob_id",
    "heartbeat_consumer_entry",
    "predefined_pdo_base",
    "sdo_request_cob_id",
    "sdo_response_cob_id",
    "sync_counter",
    "transmission_text",
]
