"""Build the node's CANopen object dictionary and write it as an EDS with canopen.

The EDS text is produced only by `canopen.objectdictionary.export_od`. Two things
canopen 2.4.1 cannot express through its API are handled here, each minimally:

* Node-id relative COB-IDs: the exporter writes `ODVariable.default_raw` verbatim when
  it is set (that is how an imported "$NODEID+0x180" survives a round trip), so PDO
  COB-IDs get `default_raw = "$NODEID+0x..."`. `canopen.RemoteNode(node_id, eds)` then
  resolves them for whatever node id it is given.
* [FileInfo] dates: `export_od` offers no way to pass file information, stamps
  ModificationDate/ModificationTime with the current wall clock (the time even with
  the month in place of the minutes), and would make every build rewrite the EDS.
  The file information is carried in the attribute the importer uses for it, and
  the two modification lines are replaced afterwards with the table's source date.
"""

from __future__ import annotations

import io
import os
import re
from datetime import UTC, datetime
from pathlib import Path

from canopen.objectdictionary import (
    ObjectDictionary,
    ODArray,
    ODRecord,
    ODVariable,
    export_od,
)

from boardproto import cia302
from boardproto.cia301 import ERROR_BEHAVIOUR_INDEX, SYNC_COB_ID, ErrorBehaviour, FunctionCode, emcy_cob_id
from boardproto.cpp_header import banner
from boardproto.table import (
    BoardTable,
    DataType,
    Field,
    HilIo,
    Pdo,
    PdoDirection,
    Recorder,
    RecorderObject,
    RecorderStatusSub,
    RecorderTriggerSub,
)

# StorageLocation values (a CANopenNode convention; CiA 306 leaves the key free):
# stored fields survive a reset once 0x1010 sub 1 was written, the rest do not.
STORAGE_PERSISTENT = "PERSIST"
STORAGE_VOLATILE = "RAM"

# 0x1010 / 0x1011 sub 1..3 read value: bit 0 = the device saves/restores on command.
SAVES_ON_COMMAND = 0x0000_0001
# 0x1010 / 0x1011 sub-indices: 1 all parameters, 2 communication (0x1000..0x1FFF), 3 application.
STORE_GROUPS = ((1, "all"), (2, "communication"), (3, "application"))
# 0x1016 sub n: bits 16..23 the monitored node id, bits 0..15 the consumer time in ms (CiA 301,
# 7.5.2.31); 0 = entry unused.
CONSUMER_HEARTBEAT_UNUSED = 0
# sub 1 COB-ID, 2 type, 3 inhibit, (4 reserved), 5 event timer; TPDOs also 6 SYNC start value.
RPDO_COMMUNICATION_SUBINDICES = 5
TPDO_COMMUNICATION_SUBINDICES = 6
# What CiA 301 defines that this node does not implement, and why. Written into the EDS's
# [Comments] and repeated in the conformance statement, docs/conformance.md.
NOT_SUPPORTED = (
    "Not supported: node guarding and life guarding (0x100C/0x100D; optional, deprecated by",
    "CiA 301 in favour of the heartbeat, which the node produces). Remote frames (RTR): every",
    "TPDO COB-ID has bit 30 set; transmission types 252/253 are refused. SYNC producer, TIME,",
    "multiple SDO servers, SDO client. Error behaviour 0x1029: sub 1 (communication errors,",
    "a heartbeat event of 0x1016) only; no device profile or manufacturer error classes.",
)
SUPPORTED_BITRATES = frozenset({125_000, 250_000, 500_000, 1_000_000})


def _variable(
    name: str,
    index: int,
    subindex: int,
    data_type: DataType,
    access: str,
    default: float | str | None,
    *,
    pdo_mappable: bool = False,
) -> ODVariable:
    variable = ODVariable(name, index, subindex)
    variable.data_type = int(data_type)
    variable.access_type = access
    variable.default = default
    variable.pdo_mappable = pdo_mappable
    return variable


def _array(
    name: str, index: int, count_name: str, count: int, count_access: str, members: list[ODVariable]
) -> ODArray:
    array = ODArray(name, index)
    array.add_member(_variable(count_name, index, 0, DataType.UNSIGNED8, count_access, count))
    for member in members:
        array.add_member(member)
    return array


def _field_variable(field: Field) -> ODVariable:
    variable = _variable(
        field.name,
        field.index,
        field.subindex,
        field.data_type,
        field.access.value,
        field.default if field.data_type is DataType.REAL32 else int(field.default),
        pdo_mappable=True,
    )
    if field.data_type is DataType.REAL32:
        variable.min, variable.max = field.min, field.max
    else:
        variable.min, variable.max = int(field.min), int(field.max)
        if field.default < 0:  # the exporter would write "0x-..." (hex of a negative number)
            variable.default_raw = str(int(field.default))
    variable.unit = field.unit
    variable.description = field.description
    variable.storage_location = STORAGE_PERSISTENT if field.stored else STORAGE_VOLATILE
    return variable


def _io_variable(io_object: HilIo) -> ODVariable:
    # Raw registers start at 0, or at the nearest end of their range if 0 is outside it.
    default = min(max(0, io_object.min), io_object.max)
    variable = _variable(
        io_object.name,
        io_object.index,
        0,
        io_object.data_type,
        io_object.access.value,
        default,
        pdo_mappable=True,
    )
    variable.min = io_object.min
    variable.max = io_object.max
    variable.unit = io_object.unit
    variable.description = io_object.description
    variable.storage_location = STORAGE_VOLATILE
    return variable


def _pdo_records(pdo: Pdo, default_node_id: int) -> tuple[ODRecord, ODRecord]:
    communication = ODRecord(f"{pdo.name} communication parameter", pdo.communication_index)
    index = pdo.communication_index
    is_tpdo = pdo.direction is PdoDirection.TPDO
    communication.add_member(
        _variable(
            "Highest sub-index supported",
            index,
            0,
            DataType.UNSIGNED8,
            "ro",
            TPDO_COMMUNICATION_SUBINDICES if is_tpdo else RPDO_COMMUNICATION_SUBINDICES,
        )
    )
    cob_id = _variable(
        f"COB-ID used by {pdo.direction.value.upper()}",
        index,
        1,
        DataType.UNSIGNED32,
        "rw",
        pdo.cob_id_value(default_node_id),
    )
    # Written verbatim by the exporter; resolved per node id by import_od / RemoteNode.
    cob_id.default_raw = f"$NODEID+0x{pdo.cob_id_base | pdo.cob_id_flags:X}"
    cob_id.relative = True
    communication.add_member(cob_id)
    communication.add_member(
        _variable("Transmission type", index, 2, DataType.UNSIGNED8, "rw", pdo.transmission_type)
    )
    communication.add_member(
        _variable("Inhibit time", index, 3, DataType.UNSIGNED16, "rw", pdo.inhibit_time_100us)
    )
    communication.add_member(
        _variable("Event timer", index, 5, DataType.UNSIGNED16, "rw", pdo.event_timer_ms)
    )
    if is_tpdo:
        # 0 = not used; with a SYNC counter (0x1019 > 0) the first transmission is at the
        # SYNC whose counter equals it.
        start = _variable("SYNC start value", index, 6, DataType.UNSIGNED8, "rw", 0)
        start.min, start.max = 0, 240
        communication.add_member(start)

    mapping = ODRecord(f"{pdo.name} mapping parameter", pdo.mapping_index)
    index = pdo.mapping_index
    mapping.add_member(
        _variable("Number of mapped objects", index, 0, DataType.UNSIGNED8, "rw", len(pdo.entries))
    )
    values = [entry.mapping_value for entry in pdo.entries]
    values += [0] * (8 - len(values))
    for subindex, value in enumerate(values, start=1):
        mapping.add_member(
            _variable(f"Mapped object {subindex}", index, subindex, DataType.UNSIGNED32, "rw", value)
        )
    return communication, mapping


def _add_communication_objects(od: ObjectDictionary, table: BoardTable) -> None:
    node = table.node
    od.add_object(_variable("Device type", 0x1000, 0, DataType.UNSIGNED32, "ro", node.device_type))
    od.add_object(_variable("Error register", 0x1001, 0, DataType.UNSIGNED8, "ro", 0, pdo_mappable=True))
    od.add_object(
        _array(
            "Pre-defined error field",
            0x1003,
            "Number of errors",
            0,
            "rw",
            [
                _variable(f"Standard error field {n}", 0x1003, n, DataType.UNSIGNED32, "ro", 0)
                for n in range(1, node.error_history_length + 1)
            ],
        )
    )
    od.add_object(_variable("COB-ID SYNC", 0x1005, 0, DataType.UNSIGNED32, "rw", SYNC_COB_ID))
    od.add_object(
        _variable(
            "Manufacturer device name",
            0x1008,
            0,
            DataType.VISIBLE_STRING,
            "const",
            node.device_name,
        )
    )
    od.add_object(
        _variable(
            "Manufacturer hardware version",
            0x1009,
            0,
            DataType.VISIBLE_STRING,
            "const",
            node.hardware_version,
        )
    )
    od.add_object(
        _variable(
            "Manufacturer software version",
            0x100A,
            0,
            DataType.VISIBLE_STRING,
            "const",
            node.software_version,
        )
    )
    for index, array_name, verb in (
        (0x1010, "Store parameters", "Save"),
        (0x1011, "Restore default parameters", "Restore"),
    ):
        od.add_object(
            _array(
                array_name,
                index,
                "Highest sub-index supported",
                len(STORE_GROUPS),
                "ro",
                [
                    _variable(
                        f"{verb} {group} parameters", index, sub, DataType.UNSIGNED32, "rw", SAVES_ON_COMMAND
                    )
                    for sub, group in STORE_GROUPS
                ],
            )
        )
    emcy_cob_id_object = _variable(
        "COB-ID EMCY", 0x1014, 0, DataType.UNSIGNED32, "ro", emcy_cob_id(node.default_node_id)
    )
    emcy_cob_id_object.default_raw = f"$NODEID+0x{FunctionCode.SYNC_EMCY:X}"
    emcy_cob_id_object.relative = True
    od.add_object(emcy_cob_id_object)
    od.add_object(
        _array(
            "Consumer heartbeat time",
            0x1016,
            "Highest sub-index supported",
            node.heartbeat_consumers,
            "ro",
            [
                _variable(
                    f"Consumer heartbeat time {n}",
                    0x1016,
                    n,
                    DataType.UNSIGNED32,
                    "rw",
                    CONSUMER_HEARTBEAT_UNUSED,
                )
                for n in range(1, node.heartbeat_consumers + 1)
            ],
        )
    )
    od.add_object(
        _variable("Producer heartbeat time", 0x1017, 0, DataType.UNSIGNED16, "rw", node.heartbeat_ms)
    )
    overflow = _variable("Synchronous counter overflow value", 0x1019, 0, DataType.UNSIGNED8, "rw", 0)
    overflow.min, overflow.max = 0, 240  # 1 and 241..255 are reserved: refused
    od.add_object(overflow)
    default_behaviour = ErrorBehaviour.PRE_OPERATIONAL
    communication_error = _variable(
        "Communication error", ERROR_BEHAVIOUR_INDEX, 1, DataType.UNSIGNED8, "rw", default_behaviour
    )
    communication_error.min, communication_error.max = min(ErrorBehaviour), max(ErrorBehaviour)
    behaviour = _array("Error behaviour", ERROR_BEHAVIOUR_INDEX, "Highest sub-index supported", 1, "ro", [])
    behaviour.add_member(communication_error)
    od.add_object(behaviour)
    identity = ODRecord("Identity object", 0x1018)
    for subindex, name, value in (
        (0, "Highest sub-index supported", 4),
        (1, "Vendor-ID", node.vendor_id),
        (2, "Product code", node.product_code),
        (3, "Revision number", node.revision),
        (4, "Serial number", 0),
    ):
        data_type = DataType.UNSIGNED8 if subindex == 0 else DataType.UNSIGNED32
        identity.add_member(_variable(name, 0x1018, subindex, data_type, "ro", value))
    od.add_object(identity)
    od.add_object(
        _array(
            "Verify configuration",
            0x1020,
            "Highest sub-index supported",
            2,
            "ro",
            [
                _variable("Configuration date", 0x1020, 1, DataType.UNSIGNED32, "rw", 0),
                _variable("Configuration time", 0x1020, 2, DataType.UNSIGNED32, "rw", 0),
            ],
        )
    )

    for pdo in table.pdos:
        for record in _pdo_records(pdo, node.default_node_id):
            od.add_object(record)
    for program_object in _program_download_objects():
        od.add_object(program_object)


def _program_download_objects() -> list[ODArray]:
    """CiA 302-3 program download (boardproto.cia302): one program, sub PROGRAM_NUMBER."""
    objects = []
    running = int(cia302.ProgramControl.START)
    for index, name, data_type, access, default in (
        (cia302.PROGRAM_DATA_INDEX, "Program data", DataType.DOMAIN, "wo", None),
        (cia302.PROGRAM_CONTROL_INDEX, "Program control", DataType.UNSIGNED8, "rw", running),
        # The running image's CRC-32: no value an EDS could know.
        (cia302.SOFTWARE_ID_INDEX, "Program software identification", DataType.UNSIGNED32, "ro", None),
        (cia302.FLASH_STATUS_INDEX, "Flash status identification", DataType.UNSIGNED32, "ro", 0),
    ):
        member = _variable(name, index, cia302.PROGRAM_NUMBER, data_type, access, default)
        highest = "Highest sub-index supported"
        objects.append(_array(name, index, highest, cia302.PROGRAM_NUMBER, "ro", [member]))
    return objects


def _limited(variable: ODVariable, low: float, high: float) -> ODVariable:
    variable.min, variable.max = low, high
    return variable


def _recorder_objects(table: BoardTable, recorder: Recorder) -> list[ODVariable | ODArray | ODRecord]:
    """The recorder's objects (board.toml's [recorder] comment says what each does)."""
    state_index = recorder.index_of(RecorderObject.STATE)
    state = _variable(
        RecorderObject.STATE.object_name,
        state_index,
        0,
        DataType.UNSIGNED8,
        "rw",
        table.enum("recorder_state").value("idle").value,
    )
    state.description = "A recorder_state value; write armed to (re-)arm, idle to stop"

    channels_index = recorder.index_of(RecorderObject.CHANNELS)
    channels = _array(
        RecorderObject.CHANNELS.object_name,
        channels_index,
        "Channels in use",
        0,
        "rw",
        [
            _limited(
                _variable(f"Channel {n}", channels_index, n, DataType.UNSIGNED16, "rw", 0),
                0,
                0xFFFF,
            )
            for n in range(1, recorder.max_channels + 1)
        ],
    )
    channels[0].min, channels[0].max = 0, recorder.max_channels

    divider = _limited(
        _variable(
            RecorderObject.DIVIDER.object_name,
            recorder.index_of(RecorderObject.DIVIDER),
            0,
            DataType.UNSIGNED16,
            "rw",
            1,
        ),
        1,
        0xFFFF,
    )
    samples = _limited(
        _variable(
            RecorderObject.SAMPLES.object_name,
            recorder.index_of(RecorderObject.SAMPLES),
            0,
            DataType.UNSIGNED32,
            "rw",
            recorder.default_samples,
        ),
        1,
        recorder.buffer_values,
    )

    trigger_index = recorder.index_of(RecorderObject.TRIGGER)
    trigger = ODRecord(RecorderObject.TRIGGER.object_name, trigger_index)
    trigger.add_member(
        _variable(
            "Highest sub-index supported", trigger_index, 0, DataType.UNSIGNED8, "ro", max(RecorderTriggerSub)
        )
    )
    immediate = table.enum("recorder_trigger").value("immediate").value
    rising = table.enum("recorder_edge").value("rising").value
    for sub, data_type, default in (
        (RecorderTriggerSub.SOURCE, DataType.UNSIGNED8, immediate),
        (RecorderTriggerSub.FIELD, DataType.UNSIGNED16, 0),
        (RecorderTriggerSub.LEVEL, DataType.REAL32, 0.0),
        (RecorderTriggerSub.EDGE, DataType.UNSIGNED8, rising),
        (RecorderTriggerSub.MASK, DataType.UNSIGNED32, 0),
        (RecorderTriggerSub.PRE_TRIGGER_PERCENT, DataType.UNSIGNED8, 0),
    ):
        member = _variable(sub.name.lower(), trigger_index, sub, data_type, "rw", default)
        if sub is RecorderTriggerSub.PRE_TRIGGER_PERCENT:
            member.min, member.max = 0, 100
        trigger.add_member(member)

    status_index = recorder.index_of(RecorderObject.STATUS)
    status = ODRecord(RecorderObject.STATUS.object_name, status_index)
    status.add_member(
        _variable(
            "Highest sub-index supported", status_index, 0, DataType.UNSIGNED8, "ro", max(RecorderStatusSub)
        )
    )
    for status_sub in RecorderStatusSub:
        status.add_member(
            _variable(status_sub.name.lower(), status_index, status_sub, DataType.UNSIGNED32, "ro", 0)
        )

    data = _variable(
        RecorderObject.DATA.object_name,
        recorder.index_of(RecorderObject.DATA),
        0,
        DataType.DOMAIN,
        "ro",
        None,
    )
    data.description = "The recording (boardproto.recording); readable when idle or done"
    return [state, channels, divider, samples, trigger, status, data]


def build_object_dictionary(table: BoardTable) -> ObjectDictionary:
    """The node's whole object dictionary, as the firmware implements it."""
    od = ObjectDictionary()
    info = od.device_information
    info.vendor_name = "hil-rig"
    info.vendor_number = table.node.vendor_id
    info.product_name = table.node.device_name
    info.product_number = table.node.product_code
    info.revision_number = table.node.revision
    info.order_code = ""
    info.allowed_baudrates = set(SUPPORTED_BITRATES)
    info.simple_boot_up_master = False
    info.simple_boot_up_slave = True
    info.granularity = 8  # objects are mapped in whole bytes or more
    info.dynamic_channels_supported = False
    info.group_messaging = False
    info.nr_of_RXPDO = len(table.rpdos)
    info.nr_of_TXPDO = len(table.tpdos)
    info.LSS_supported = True  # CiA 305 LSS slave (firmware/canopen/LssSlave.hpp)
    od.comments = "\n".join((banner(table).removeprefix("// "), *NOT_SUPPORTED))

    _add_communication_objects(od, table)
    for field in table.fields:
        if field.subindex == 0:
            od.add_object(_field_variable(field))
    for field_array in table.arrays:
        members = [_field_variable(table.field(name)) for name in field_array.members]
        array = _array(
            field_array.name,
            field_array.index,
            "Highest sub-index supported",
            field_array.count,
            "ro",
            members,
        )
        array.description = field_array.description
        od.add_object(array)
    for io_object in (*table.hil_inputs, *table.hil_outputs):
        od.add_object(_io_variable(io_object))
    if table.recorder is not None:
        for recorder_object in _recorder_objects(table, table.recorder):
            od.add_object(recorder_object)
    return od


def source_date(table: BoardTable) -> datetime:
    """SOURCE_DATE_EPOCH when set (reproducible builds), else board.toml's mtime."""
    epoch = os.environ.get("SOURCE_DATE_EPOCH")
    if epoch is not None and epoch.isdigit():
        return datetime.fromtimestamp(int(epoch), tz=UTC)
    return datetime.fromtimestamp(Path(table.source).stat().st_mtime, tz=UTC)


def generate_eds(table: BoardTable) -> str:
    """The EDS text, written by canopen's exporter."""
    od = build_object_dictionary(table)
    stamp = source_date(table)
    eds_date, eds_time = stamp.strftime("%m-%d-%Y"), stamp.strftime("%I:%M%p")
    file_info = {
        "FileName": "board.eds",
        "FileVersion": 1,
        "FileRevision": 0,
        "EdsVersion": "4.0",
        "Description": f"{table.node.device_name}: board fields and HIL I/O",
        "CreationDate": eds_date,
        "CreationTime": eds_time,
        "CreatedBy": "protocol/boardproto",
        "ModifiedBy": "protocol/boardproto",
    }
    # The attribute import_eds() fills from [FileInfo] and export_eds() reads back.
    # setattr spells the name literally: a dunder-prefixed attribute is easy to break by
    # moving this line into a class, where Python would mangle it.
    setattr(od, "__edsFileInfo", file_info)
    buffer = io.StringIO()
    export_od(od, buffer, doc_type="eds")
    text = buffer.getvalue()
    text = re.sub(r"(?m)^ModificationDate=.*$", f"ModificationDate={eds_date}", text, count=1)
    return re.sub(r"(?m)^ModificationTime=.*$", f"ModificationTime={eds_time}", text, count=1)
