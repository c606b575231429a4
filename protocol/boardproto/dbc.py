"""Build a DBC of the default PDO frames with cantools and write it with its dumper.

The DBC describes one node id (the table's default unless told otherwise): PDO
COB-IDs depend on the node id and a DBC has no way to say "base + node id".

Signals whose object declares `values` get a value table (VAL_), so cantools, SavvyCAN and
cabana print `velocity` instead of 1:

- an [[enum]]: one name per value.
- a [[bitset]]: DBC has no bit-flag tables, and a per-bit signal cannot work here: fault_flags
  travels as a REAL32, so the bus carries the float's IEEE 754 bits, not the flag bits. Instead
  every combination of the named bits gets a name, lowest bit first and joined by "|" like
  Python's IntFlag (3 -> "motor_encoder_stale|output_encoder_stale"), and 0 is "none". That is
  2**bits names, so above MAX_COMBINED_BITS only the single bits and 0 are named and a value with
  several bits set decodes as its number.

cantools 45 looks a float signal's choice up by int(value): 1.5 decodes as the name of 1, and a
NaN or infinite value raises (ValueError/OverflowError) instead of decoding. The rig decodes
with `decode_choices=False` for its numbers; tools that show names are for people reading a log.
"""

from __future__ import annotations

from cantools.database.can import Database, Message, Node, Signal
from cantools.database.conversion import BaseConversion
from cantools.database.namedsignalvalue import NamedSignalValue

from boardproto.loader import MAX_NODE_ID, default_cob_id_base
from boardproto.table import BitSet, BoardTable, DataType, Pdo, PdoDirection, ValueEnum

FIRMWARE_NODE = "joint_firmware"
RIG_NODE = "rig"

NO_FLAGS = "none"
"""The name of a bitset's 0 in the value table."""

FLAG_SEPARATOR = "|"

MAX_COMBINED_BITS = 8
"""A bitset of up to this many named bits names every combination (at most 256 names)."""

HIGHEST_SHARED_NODE_ID = 63
"""board.toml: PDO 5..8 default to PDO 1..4's COB-ID + 0x40, so node ids stay below 64."""


def value_choices(values: ValueEnum | BitSet) -> dict[int, NamedSignalValue]:
    """The DBC value table of an [[enum]] or [[bitset]], by number."""
    if isinstance(values, ValueEnum):
        names = {value.value: value.name for value in values.values}
    else:
        names = _bitset_names(values)
    return {number: NamedSignalValue(number, names[number]) for number in sorted(names)}


def _bitset_names(bitset: BitSet) -> dict[int, str]:
    bits = sorted(bitset.bits, key=lambda flag: flag.bit)
    names = {0: NO_FLAGS}
    if len(bits) > MAX_COMBINED_BITS:
        names.update((flag.mask, flag.name) for flag in bits)
        return names
    for subset in range(1, 1 << len(bits)):
        chosen = [flag for position, flag in enumerate(bits) if subset >> position & 1]
        names[sum(flag.mask for flag in chosen)] = FLAG_SEPARATOR.join(flag.name for flag in chosen)
    return names


def _signals(table: BoardTable, pdo: Pdo, receiver: str) -> list[Signal]:
    signals = []
    start_bit = 0
    for mapped in pdo.entries:
        entry = table.entry(mapped.name)
        values = table.values_of(mapped.name)
        signals.append(
            Signal(
                name=mapped.name,
                start=start_bit,
                length=mapped.bits,
                byte_order="little_endian",  # CANopen is little-endian
                is_signed=entry.data_type.is_signed,
                # Raw value = physical value: fields travel in SI units, HIL I/O as raw counts.
                conversion=BaseConversion.factory(
                    choices=value_choices(values) if values is not None else None,
                    is_float=entry.data_type is DataType.REAL32,
                ),
                minimum=entry.min,
                maximum=entry.max,
                unit=entry.unit,
                comment=entry.description,
                receivers=[receiver],
            )
        )
        start_bit += mapped.bits
    return signals


def dbc_pdos(table: BoardTable) -> list[Pdo]:
    """The PDOs the DBC describes: enabled, with something mapped."""
    return [pdo for pdo in table.pdos if pdo.enabled and pdo.entries]


def build_database(table: BoardTable, node_id: int | None = None) -> Database:
    """One message per enabled, non-empty default PDO, for node_id (default: the table's)."""
    node_id = table.node.default_node_id if node_id is None else node_id
    messages = []
    for pdo in dbc_pdos(table):
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


def node_id_warning(table: BoardTable, node_id: int) -> str | None:
    """Why node_id is a poor choice for this table, or None.

    PDO 5..8 keep the default COB-ID of PDO 1..4 + 0x40 unless board.toml sets cob_id_base; for
    a node id above 63 that is the identifier of a PDO 1..4 of node id - 64 (TPDO5 of node 0x50
    is 0x210, RPDO1 of node 0x10), so a second board at node id - 64 would take the frame for its
    own.
    """
    if node_id <= HIGHEST_SHARED_NODE_ID:
        return None
    shifted = [
        pdo
        for pdo in dbc_pdos(table)
        if pdo.number > 4 and pdo.cob_id_base == default_cob_id_base(pdo.direction, pdo.number)
    ]
    if not shifted:
        return None
    clashes = ", ".join(
        f"{pdo.name} 0x{pdo.cob_id(node_id):03X}{_owner(pdo.cob_id(node_id))}" for pdo in shifted
    )
    return (
        f"node id 0x{node_id:02X} is above {HIGHEST_SHARED_NODE_ID}: PDO 5..8 keep their default "
        f"COB-IDs (PDO 1..4's + 0x40), the identifiers of PDO 1..4 of node id - 64: {clashes}; "
        "keep node ids below 64 on a bus that uses PDO 5..8, or set their cob_id_base in board.toml"
    )


def _owner(cob_id: int) -> str:
    """' = RPDO1 of node 0x10' when cob_id is a pre-defined PDO 1..4 COB-ID of a node."""
    for direction in PdoDirection:
        for number in range(1, 5):
            base = default_cob_id_base(direction, number)
            if base is not None and 1 <= cob_id - base <= MAX_NODE_ID:
                return f" = {direction.value.upper()}{number} of node 0x{cob_id - base:02X}"
    return ""
