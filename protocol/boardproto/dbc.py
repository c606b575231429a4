"""Build a DBC of the default PDO frames with cantools and write it with its dumper.

The DBC describes one node id (the table's default unless told otherwise): PDO
COB-IDs depend on the node id and a DBC has no way to say "base + node id".
"""

from __future__ import annotations

from cantools.database.can import Database, Message, Node, Signal
from cantools.database.conversion import IdentityConversion

from boardproto.table import BoardTable, DataType, Pdo, PdoDirection

FIRMWARE_NODE = "joint_firmware"
RIG_NODE = "rig"


def _signals(table: BoardTable, pdo: Pdo, receiver: str) -> list[Signal]:
    signals = []
    start_bit = 0
    for mapped in pdo.entries:
        entry = table.entry(mapped.name)
        is_float = entry.data_type is DataType.REAL32
        signals.append(
            Signal(
                name=mapped.name,
                start=start_bit,
                length=mapped.bits,
                byte_order="little_endian",  # CANopen is little-endian
                is_signed=entry.data_type.is_signed,
                # Raw value = physical value: fields travel in SI units, HIL I/O as raw counts.
                conversion=IdentityConversion(is_float=is_float),
                minimum=entry.min,
                maximum=entry.max,
                unit=entry.unit,
                comment=entry.description,
                receivers=[receiver],
            )
        )
        start_bit += mapped.bits
    return signals


def build_database(table: BoardTable, node_id: int | None = None) -> Database:
    """One message per enabled, non-empty default PDO, for node_id (default: the table's)."""
    node_id = table.node.default_node_id if node_id is None else node_id
    messages = []
    for pdo in table.pdos:
        if not pdo.enabled or not pdo.entries:
            continue
        sender, receiver = (
            (FIRMWARE_NODE, RIG_NODE) if pdo.direction is PdoDirection.TPDO else (RIG_NODE, FIRMWARE_NODE)
        )
        messages.append(
            Message(
                frame_id=pdo.cob_id(node_id),
                name=pdo.name,
                length=pdo.length_bytes,
                signals=_signals(table, pdo, receiver),
                senders=[sender],
                comment=f"{pdo.name} of node 0x{node_id:02X}, transmission type {pdo.transmission_type}",
            )
        )
    nodes = [Node(FIRMWARE_NODE, comment=table.node.device_name), Node(RIG_NODE)]
    return Database(messages=messages, nodes=nodes, version="")


def generate_dbc(table: BoardTable, node_id: int | None = None) -> str:
    return build_database(table, node_id).as_dbc_string()
