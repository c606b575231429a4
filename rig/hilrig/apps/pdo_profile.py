"""Write one of the table's PDO profiles (board.toml's [[pdo_profile]]) to a board over SDO and
store it, so it is the board's mapping from its next start on too::

    hilrig pdo apply lean          # the profile that fits 1 Mbit/s at 1 kHz

Remapping is allowed in pre-operational only (CiA 301 leaves remapping in operational
optional, and this firmware refuses it), so the board is sent NMT "enter pre-operational" first
and left there: its master starts it again. Each PDO is written in the order CiA 301 asks
(canopen's `PdoMap.save`: disabled, parameters, mapping count 0, entries, count, COB-ID), then
the SYNC counter overflow value (0x1019) the profile's start values need, then "store
communication parameters" (0x1010:02).
"""

from __future__ import annotations

from boardproto.cia301 import (
    STORE_COMMUNICATION,
    STORE_PARAMETERS_INDEX,
    STORE_SIGNATURE,
    SYNC_COUNTER_OVERFLOW_INDEX,
    NmtCommand,
)
from boardproto.table import Pdo, PdoDirection, PdoProfile
from hilrig.wire.node import BoardNode


def _write(node: BoardNode, pdo: Pdo) -> None:
    maps = node.remote.rpdo if pdo.direction is PdoDirection.RPDO else node.remote.tpdo
    pdo_map = maps[pdo.number]
    pdo_map.clear()
    for entry in pdo.entries:
        pdo_map.add_variable(entry.index, entry.subindex, entry.bits)
    pdo_map.cob_id = pdo.cob_id(node.node_id)
    pdo_map.trans_type = pdo.transmission_type
    pdo_map.inhibit_time = pdo.inhibit_time_100us
    pdo_map.event_timer = pdo.event_timer_ms
    if pdo.direction is PdoDirection.TPDO:
        pdo_map.sync_start_value = pdo.sync_start
        pdo_map.rtr_allowed = False  # the node answers no remote frame (bit 30 set)
    pdo_map.enabled = pdo.enabled and bool(pdo.entries)
    node.call_sdo(f"write {pdo.name} of the profile", pdo_map.save)


def apply_pdo_profile(node: BoardNode, profile: PdoProfile) -> None:
    """Write `profile` to the node (pre-operational from here on) and store it; a refused write
    is SdoAbortError naming what was written."""
    node.nmt(NmtCommand.ENTER_PRE_OPERATIONAL)
    node.read_pdo_configuration(from_node=True)  # canopen's maps of the node's records
    for pdo in (*profile.rpdos, *profile.tpdos):
        _write(node, pdo)
    node.download(SYNC_COUNTER_OVERFLOW_INDEX, 0, bytes([profile.sync_counter_overflow]))
    node.download(STORE_PARAMETERS_INDEX, STORE_COMMUNICATION, STORE_SIGNATURE.to_bytes(4, "little"))
    node.read_pdo_configuration(from_node=True)  # what the node now has, as it says


__all__ = ["apply_pdo_profile"]
