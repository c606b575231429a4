"""The EDS round-trips through canopen: import_od and RemoteNode see exactly the table."""

from __future__ import annotations

import configparser
from pathlib import Path

import canopen
import pytest
from canopen.objectdictionary import ODArray, ODRecord, ODVariable, datatypes, import_od

from boardproto import BoardTable, Pdo
from boardproto.cia301 import (
    ERROR_BEHAVIOUR_INDEX,
    SYNC_COB_ID,
    ErrorBehaviour,
    FunctionCode,
    cob_id,
    emcy_cob_id,
)
from boardproto.eds import generate_eds
from boardproto.table import DataType


@pytest.fixture(scope="module")
def eds_path(generated_dir: Path) -> Path:
    return generated_dir / "board.eds"


@pytest.fixture(scope="module")
def od(eds_path: Path, table: BoardTable) -> canopen.ObjectDictionary:
    return import_od(str(eds_path), node_id=table.node.default_node_id)


@pytest.fixture(scope="module")
def eds_sections(eds_path: Path) -> configparser.RawConfigParser:
    parser = configparser.RawConfigParser()
    parser.optionxform = str  # type: ignore[assignment,method-assign]
    parser.read(eds_path)
    return parser


def _variable(od: canopen.ObjectDictionary, index: int, subindex: int = 0) -> ODVariable:
    entry = od[index]
    variable = entry if subindex == 0 and isinstance(entry, ODVariable) else entry[subindex]
    assert isinstance(variable, ODVariable)
    return variable


def test_every_field_round_trips(
    od: canopen.ObjectDictionary, table: BoardTable, eds_sections: configparser.RawConfigParser
) -> None:
    for field in table.fields:
        # A plain field is the object of its name; an [[array]]'s member is a sub of the array.
        variable = od[field.name] if field.subindex == 0 else od.get_variable(field.index, field.subindex)
        assert isinstance(variable, ODVariable), field.name
        assert (variable.index, variable.subindex) == (field.index, field.subindex), field.name
        assert variable.name == field.name
        # A board field is REAL32 on the bus; a CiA 402 object has its profile's integer type.
        assert variable.data_type == field.data_type.value, field.name
        assert variable.access_type == field.access.value, field.name
        assert variable.default == field.default, field.name
        assert variable.unit == field.unit, field.name
        assert variable.description == field.description, field.name
        assert variable.pdo_mappable, field.name
        assert variable.storage_location == ("PERSIST" if field.stored else "RAM"), field.name
        # canopen 2.4.1 parses LowLimit/HighLimit as integers only, so REAL32 limits are
        # checked in the EDS text itself.
        section = eds_sections[f"{field.index:04X}" + (f"sub{field.subindex}" if field.subindex else "")]
        if field.data_type is not DataType.REAL32:
            assert (variable.min, variable.max) == (field.min, field.max), field.name
            continue
        assert float(section["LowLimit"]) == field.min, field.name
        assert float(section["HighLimit"]) == field.max, field.name


def test_every_hil_io_object_round_trips(od: canopen.ObjectDictionary, table: BoardTable) -> None:
    for io_object in (*table.hil_inputs, *table.hil_outputs):
        variable = od[io_object.name]
        assert isinstance(variable, ODVariable)
        assert variable.index == io_object.index
        assert variable.data_type == io_object.data_type.value
        assert variable.access_type == io_object.access.value
        assert (variable.min, variable.max) == (io_object.min, io_object.max), io_object.name
        assert variable.unit == io_object.unit
        assert variable.pdo_mappable


def test_communication_objects(od: canopen.ObjectDictionary, table: BoardTable) -> None:
    node = table.node
    assert _variable(od, 0x1000).default == node.device_type
    assert _variable(od, 0x1001).data_type == datatypes.UNSIGNED8
    errors = od[0x1003]
    assert isinstance(errors, ODArray)
    assert sorted(errors.subindices) == list(range(node.error_history_length + 1))
    assert _variable(od, 0x1003, 0).access_type == "rw"  # write 0 clears the history
    assert _variable(od, 0x1005).default == SYNC_COB_ID
    assert _variable(od, 0x1008).default == "hil-joint-firmware"
    assert _variable(od, 0x1008).data_type == datatypes.VISIBLE_STRING
    assert _variable(od, 0x1009).default == node.hardware_version
    assert _variable(od, 0x100A).default == node.software_version
    for index in (0x1010, 0x1011):  # 1 all, 2 communication, 3 application
        assert isinstance(od[index], ODArray)
        assert _variable(od, index, 0).default == 3
        for sub in (1, 2, 3):
            assert _variable(od, index, sub).access_type == "rw"
            assert _variable(od, index, sub).default == 1  # saves on command
    assert _variable(od, 0x1014).default == emcy_cob_id(node.default_node_id)
    assert _variable(od, 0x1014).access_type == "ro"
    assert _variable(od, 0x1019).default == 0
    assert (_variable(od, 0x1019).min, _variable(od, 0x1019).max) == (0, 240)
    verify = od[0x1020]
    assert isinstance(verify, ODArray)
    assert sorted(verify.subindices) == [0, 1, 2]
    assert _variable(od, 0x1017).default == node.heartbeat_ms == 100
    consumers = od[0x1016]
    assert isinstance(consumers, ODArray)
    assert sorted(consumers.subindices) == list(range(node.heartbeat_consumers + 1))
    assert _variable(od, 0x1016, 0).default == node.heartbeat_consumers
    assert _variable(od, 0x1016, 0).access_type == "ro"
    assert _variable(od, 0x1016, 0).data_type == datatypes.UNSIGNED8
    for sub in range(1, node.heartbeat_consumers + 1):
        entry = _variable(od, 0x1016, sub)
        assert (entry.data_type, entry.access_type, entry.default) == (datatypes.UNSIGNED32, "rw", 0)
    behaviour = od[ERROR_BEHAVIOUR_INDEX]
    assert isinstance(behaviour, ODArray) and sorted(behaviour.subindices) == [0, 1]
    communication_error = _variable(od, ERROR_BEHAVIOUR_INDEX, 1)
    assert (communication_error.data_type, communication_error.access_type) == (datatypes.UNSIGNED8, "rw")
    assert communication_error.default == ErrorBehaviour.PRE_OPERATIONAL  # CiA 301's default
    assert (communication_error.min, communication_error.max) == (0, ErrorBehaviour.STOPPED)
    identity = od[0x1018]
    assert isinstance(identity, ODRecord)
    assert [identity[s].default for s in (1, 2, 3)] == [
        node.vendor_id,
        node.product_code,
        node.revision,
    ]


def _pdo_layout(pdo_map: canopen.pdo.PdoMap) -> tuple[int, bool, int, list[tuple[int, int]]]:
    return (
        pdo_map.cob_id,
        pdo_map.enabled,
        pdo_map.trans_type,
        [(variable.index, variable.length) for variable in pdo_map.map],
    )


def _expected_layout(pdo: Pdo, node_id: int) -> tuple[int, bool, int, list[tuple[int, int]]]:
    return (
        pdo.cob_id(node_id),
        pdo.enabled,
        pdo.transmission_type,
        [(entry.index, entry.bits) for entry in pdo.entries],
    )


@pytest.mark.parametrize("node_id", [0x10, 0x05, 0x3F])
def test_remote_node_sees_default_pdos_for_any_node_id(
    eds_path: Path, table: BoardTable, node_id: int
) -> None:
    network = canopen.Network()  # never connected: PDO read subscribes, sends nothing
    node = canopen.RemoteNode(node_id, str(eds_path))
    network.add_node(node)
    node.rpdo.read(from_od=True)
    node.tpdo.read(from_od=True)
    assert len(node.rpdo.map) == len(table.rpdos)
    assert len(node.tpdo.map) == len(table.tpdos)
    for pdo in table.rpdos:
        assert _pdo_layout(node.rpdo.map[pdo.number]) == _expected_layout(pdo, node_id), pdo.name
    for pdo in table.tpdos:
        assert _pdo_layout(node.tpdo.map[pdo.number]) == _expected_layout(pdo, node_id), pdo.name
    assert node.tpdo.map[1].cob_id == cob_id(FunctionCode.TPDO1, node_id)
    assert node.rpdo.map[1].cob_id == cob_id(FunctionCode.RPDO1, node_id)
    assert not any(pdo_map.rtr_allowed for pdo_map in node.tpdo.map.values())


def test_remote_node_addresses_the_heartbeat_consumer_by_index(eds_path: Path, table: BoardTable) -> None:
    # What a master does to make a module watch it: 0x1016 sub 1 = (its node id << 16) | time in ms.
    node = canopen.RemoteNode(0x05, str(eds_path))
    entry = node.sdo[0x1016][1]
    assert entry.od.data_type == datatypes.UNSIGNED32
    assert entry.od.writable and entry.od.readable
    assert entry.od.encode_raw((0x01 << 16) | 150) == bytes([150, 0, 0x01, 0])
    count = node.sdo[0x1016][0]
    assert count.od.readable and not count.od.writable
    assert count.od.default == table.node.heartbeat_consumers


def test_cob_ids_are_node_relative_in_the_file(eds_sections: configparser.RawConfigParser) -> None:
    assert eds_sections["1800sub1"]["DefaultValue"] == "$NODEID+0x40000180"  # bit 30: no RTR
    assert eds_sections["1403sub1"]["DefaultValue"] == "$NODEID+0x80000500"  # RPDO4 disabled
    assert eds_sections["1014"]["DefaultValue"] == "$NODEID+0x80"


def test_tpdos_have_a_sync_start_value_and_rpdos_do_not(
    od: canopen.ObjectDictionary, table: BoardTable
) -> None:
    for pdo in table.tpdos:
        record = od[pdo.communication_index]
        assert isinstance(record, ODRecord)
        assert record[0].default == 6
        assert record[6].default == 0, pdo.name
    for pdo in table.rpdos:
        record = od[pdo.communication_index]
        assert isinstance(record, ODRecord)
        assert record[0].default == 5
        assert 6 not in record.subindices, pdo.name


def test_eds_states_what_is_not_supported(eds_sections: configparser.RawConfigParser) -> None:
    comments = " ".join(
        eds_sections["Comments"][f"Line{n}"] for n in range(1, int(eds_sections["Comments"]["Lines"]) + 1)
    )
    for topic in ("node guarding", "0x1029", "RTR"):
        assert topic in comments, topic


def test_eds_is_deterministic(table: BoardTable, eds_path: Path) -> None:
    assert generate_eds(table) == generate_eds(table) == eds_path.read_text()


def test_eds_opens_with_the_generated_banner(eds_sections: configparser.RawConfigParser) -> None:
    assert eds_sections["Comments"]["Line1"].startswith("Generated from protocol/board.toml")
    assert eds_sections["DeviceInfo"]["NrOfRXPDO"] == "4"
    assert eds_sections["DeviceInfo"]["NrOfTXPDO"] == "8"
