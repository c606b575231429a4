"""Parameter sets as DCF files (CiA 306 device configuration files): what one board stores,
saved to a file and put on the next, through python-canopen's own EDS/DCF support
(`canopen.import_od`, `canopen.export_od(..., doc_type="dcf")`): a DCF is the board's EDS with
a `ParameterValue` for each object it configures.

    od = save_dcf(remote, eds_od, table, "board.dcf")         # every stored object, read over SDO
    load_dcf(remote, "board.dcf", table, store=True)          # written, stored (0x1010), read back

What a board stores is what its 0x1010 "store parameters" keeps: the writable communication
objects (0x1005 SYNC, 0x1016 consumer heartbeat, 0x1017, 0x1019, 0x1020, the PDO communication
and mapping records, ...) except the ones that are commands (0x1003 error history clear, 0x1010,
0x1011), and the board fields board.toml marks `stored`. So a new stored communication object
is in the set once the EDS describes it as writable, and a field once the table marks it.

Loading writes each PDO the way CiA 301 wants a PDO changed (made invalid, mapping count 0,
entries, count, then its COB-ID), so a mapping of another length is accepted; the node must be
pre-operational for that, and the first refusal stops the load with the object and the abort
code in words.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import canopen
from canopen.objectdictionary import ODArray, ODRecord, ODVariable
from canopen.sdo import SdoAbortedError

from boardproto.cia301 import NODE_ID_MASK, SdoAbortCode
from boardproto.cia302 import PROGRAM_CONTROL_INDEX, PROGRAM_DATA_INDEX
from boardproto.loader import MAX_PDO_SLOTS
from boardproto.table import PDO_NOT_VALID, PdoDirection
from hilrig.errors import RigError
from hilrig.files import replacing
from hilrig.table import RigTable

STORE_PARAMETERS = 0x1010
STORE_ALL = 1
STORE_SIGNATURE = int.from_bytes(b"save", "little")
"""CiA 301: writing the ASCII bytes "save" to 0x1010 stores; any other value is refused."""
NOT_STORED = frozenset({0x1003, STORE_PARAMETERS, 0x1011, PROGRAM_DATA_INDEX, PROGRAM_CONTROL_INDEX})
"""Writable communication objects that are commands, not settings (program download's too)."""
IDENTITY = 0x1018
COMMUNICATION_END = 0x2000


class DcfError(RigError):
    """A parameter set that cannot be saved or loaded (the message says which object and why)."""


def _writable(var: ODVariable) -> bool:
    return "w" in (var.access_type or "")


def _variables(od: canopen.ObjectDictionary) -> Iterator[ODVariable]:
    for obj in od.values():
        if isinstance(obj, ODVariable):
            yield obj
        elif isinstance(obj, ODRecord | ODArray):
            yield from (var for var in obj.values() if isinstance(var, ODVariable))


def stored_objects(od: canopen.ObjectDictionary, table: RigTable) -> list[ODVariable]:
    """The objects 0x1010 stores, in index order (see the module's docstring)."""
    stored_fields = {(field.index, field.subindex) for field in table.board.fields if field.stored}
    chosen = []
    for var in _variables(od):
        if var.index < COMMUNICATION_END:
            if _writable(var) and var.index not in NOT_STORED:
                chosen.append(var)
        elif (var.index, var.subindex) in stored_fields:
            chosen.append(var)
    return sorted(chosen, key=lambda var: (var.index, var.subindex))


def _pdo_of(index: int) -> tuple[int, int] | None:
    """(communication index, mapping index) of the PDO whose record `index` is, else None."""
    for direction in PdoDirection:
        communication, mapping = direction.communication_index, direction.mapping_index
        for base in (communication, mapping):
            if base <= index < base + MAX_PDO_SLOTS:
                number = index - base
                return communication + number, mapping + number
    return None


def _describe(var: ODVariable) -> str:
    return f"0x{var.index:04X}:{var.subindex:02X} {var.qualname if hasattr(var, 'qualname') else var.name}"


def _abort_text(error: SdoAbortedError) -> str:
    try:
        return f"0x{error.code:08X} {SdoAbortCode(error.code).text}"
    except ValueError:
        return f"0x{error.code:08X}"


@dataclass(frozen=True)
class LoadReport:
    written: int
    stored: bool
    verified: int


def save_dcf(remote: canopen.RemoteNode, table: RigTable, path: Path) -> canopen.ObjectDictionary:
    """Read every stored object of `remote` over SDO into its object dictionary's `value`, and
    write the DCF (atomically: a temporary file renamed). Returns the dictionary written."""
    od = remote.object_dictionary
    for var in stored_objects(od, table):
        try:
            var.value = _sdo_variable(remote, var).raw
        except SdoAbortedError as error:
            raise DcfError(f"reading {_describe(var)}: {_abort_text(error)}") from None
        var.value_raw = _relative(var, remote.id) or _negative(var.value)
    with replacing(path) as temporary:
        canopen.export_od(od, str(temporary), doc_type="dcf")
    return od


def _relative(var: ODVariable, node_id: int) -> str | None:
    """A COB-ID the EDS gives relative to the node id ($NODEID+0x180), still relative to it
    ("$NODEID+0x180", "$NODEID+0x80000180" when made invalid), so that the DCF put on a node with
    another id configures that node's own COB-IDs; None for every other value."""
    value = var.value
    if not getattr(var, "relative", False) or not isinstance(value, int) or value & NODE_ID_MASK != node_id:
        return None
    return f"$NODEID+0x{value - node_id:X}"


def _negative(value: object) -> str | None:
    """A negative integer in decimal: canopen's exporter writes every integer in hex, a negative
    one as "0x-..." that no importer reads back; None for every other value."""
    return str(value) if isinstance(value, int) and value < 0 else None


def _sdo_variable(remote: canopen.RemoteNode, var: ODVariable) -> canopen.sdo.base.Variable:
    obj = remote.object_dictionary[var.index]
    return remote.sdo[var.index] if isinstance(obj, ODVariable) else remote.sdo[var.index][var.subindex]


def _write(remote: canopen.RemoteNode, var: ODVariable, value: float) -> None:
    try:
        _sdo_variable(remote, var).raw = value
    except SdoAbortedError as error:
        hint = ""
        if error.code == SdoAbortCode.DEVICE_STATE:
            hint = " (PDOs change in pre-operational only: `hilrig nmt preop` first)"
        raise DcfError(
            f"writing {value!r} to {_describe(var)}: refused, {_abort_text(error)}{hint}"
        ) from None


def read_dcf(path: Path, node_id: int) -> canopen.ObjectDictionary:
    """The DCF's object dictionary (canopen's import; `value` set where it has a ParameterValue)."""
    try:
        return canopen.import_od(str(path), node_id)
    except Exception as error:  # configparser, KeyError, ValueError: the file
        raise DcfError(f"{path} is not a DCF canopen can read ({error})") from None


def load_dcf(
    remote: canopen.RemoteNode, dcf: canopen.ObjectDictionary, table: RigTable, *, store: bool
) -> LoadReport:
    """Write every stored object the DCF has a value for to `remote` (PDOs in CiA 301's order),
    store them with 0x1010 if `store`, and read each back: a value that differs is an error.
    Refused before writing anything: a DCF of another product (vendor id, product code)."""
    _check_product(remote, dcf)
    values = {(var.index, var.subindex): var for var in stored_objects(dcf, table) if var.value is not None}
    pdos: dict[tuple[int, int], list[ODVariable]] = {}
    plain: list[ODVariable] = []
    for key, var in values.items():
        pdo = _pdo_of(key[0])
        (pdos.setdefault(pdo, []) if pdo else plain).append(var)
    written = 0
    for var in plain:
        _write(remote, var, var.value)
        written += 1
    for (communication, mapping), variables in sorted(pdos.items()):
        written += _write_pdo(remote, communication, mapping, {(v.index, v.subindex): v for v in variables})
    if store:
        try:
            remote.sdo[STORE_PARAMETERS][STORE_ALL].raw = STORE_SIGNATURE
        except SdoAbortedError as error:
            raise DcfError(f"storing (0x1010:01): refused, {_abort_text(error)}") from None
    verified = 0
    for var in values.values():
        got = _sdo_variable(remote, var).raw
        if got != var.value:
            raise DcfError(f"{_describe(var)} reads back {got!r}, the DCF has {var.value!r}")
        verified += 1
    return LoadReport(written=written, stored=store, verified=verified)


def _write_pdo(
    remote: canopen.RemoteNode, communication: int, mapping: int, variables: dict[tuple[int, int], ODVariable]
) -> int:
    """One PDO in CiA 301's order: COB-ID invalid, the other parameters, mapping count 0, the
    entries, the count, then the COB-ID as the DCF has it."""
    cob_id = variables.get((communication, 1))
    count = variables.get((mapping, 0))
    order: list[tuple[ODVariable, int | float]] = []
    if cob_id is not None:
        order.append((cob_id, int(cob_id.value) | PDO_NOT_VALID))
    order += [(v, v.value) for key, v in sorted(variables.items()) if key[0] == communication and key[1] != 1]
    if count is not None:
        order.append((count, 0))
    order += [(v, v.value) for key, v in sorted(variables.items()) if key[0] == mapping and key[1] != 0]
    if count is not None:
        order.append((count, count.value))
    if cob_id is not None:
        order.append((cob_id, cob_id.value))
    for var, value in order:
        _write(remote, var, value)
    return len(variables)


def _check_product(remote: canopen.RemoteNode, dcf: canopen.ObjectDictionary) -> None:
    info = dcf.device_information
    try:
        vendor = remote.sdo[IDENTITY][1].raw
        product = remote.sdo[IDENTITY][2].raw
    except SdoAbortedError as error:
        raise DcfError(f"reading the node's identity (0x1018): {_abort_text(error)}") from None
    wanted = (info.vendor_number, info.product_number)
    if None not in wanted and wanted != (vendor, product):
        raise DcfError(
            f"the DCF is for vendor 0x{wanted[0]:08X} product 0x{wanted[1]:08X}; node "
            f"0x{remote.id:02X} is vendor 0x{vendor:08X} product 0x{product:08X}: refused, nothing written"
        )
