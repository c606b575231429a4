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
STANDARD_ID_MASK = 0x7FF
SYNC_COB_ID = int(FunctionCode.SYNC_EMCY)
NMT_COB_ID = int(FunctionCode.NMT)
TIME_COB_ID = int(FunctionCode.TIME)
SYNC_COUNTER_MAX = 240
"""SYNC counters run 1..240 and wrap (CiA 301 counter overflow value 240)."""
LAST_SYNCHRONOUS_TYPE = 240
"""PDO transmission types 1..240: synchronous, every n-th SYNC; 0: acyclic synchronous;
254/255: event-driven."""


def cob_id(function: FunctionCode, node_id: int) -> int:
    """The COB-ID of a per-node service: base + node id."""
    if not 1 <= node_id <= NODE_ID_MASK:
        raise ValueError(f"node id: expected 1..127, got {node_id}")
    return int(function) + node_id


def emcy_cob_id(node_id: int) -> int:
    return cob_id(FunctionCode.SYNC_EMCY, node_id)


def heartbeat_cob_id(node_id: int) -> int:
    return cob_id(FunctionCode.HEARTBEAT, node_id)


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


__all__ = [
    "LAST_SYNCHRONOUS_TYPE",
    "NMT_COB_ID",
    "NODE_ID_MASK",
    "STANDARD_ID_MASK",
    "SYNC_COB_ID",
    "SYNC_COUNTER_MAX",
    "TIME_COB_ID",
    "FunctionCode",
    "cob_id",
    "due_at_sync",
    "emcy_cob_id",
    "heartbeat_cob_id",
    "sdo_request_cob_id",
    "sdo_response_cob_id",
    "sync_counter",
]
