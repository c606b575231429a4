"""The PDO codecs compiled from canopen's configuration and the python-can link, without a
kernel bus (the raw-socket link is exercised on vcan by tests/test_bus_smoke.py). Frames are
checked against the generated DBC with cantools, independently of the struct codecs."""

from __future__ import annotations

import itertools
import struct
from typing import ClassVar

import can
import canopen
import cantools
import pytest

from boardproto.cia301 import FunctionCode, cob_id, due_at_sync, emcy_cob_id, sync_counter
from hilrig.errors import PdoMappingError
from hilrig.rig import DEFAULT_EDS_PATH
from hilrig.transport import (
    CAN_FRAME_SIZE,
    BusLink,
    PdoDirection,
    PdoLayout,
    can_frame,
    compile_pdos,
    parse_frame,
)

NODE_ID = 0x10
TPDO1_ID, EMCY_ID = cob_id(FunctionCode.TPDO1, NODE_ID), emcy_cob_id(NODE_ID)
_channels = itertools.count()


@pytest.fixture(scope="module")
def pdos() -> tuple[dict[int, PdoLayout], dict[int, PdoLayout]]:
    network = canopen.Network()
    node = canopen.RemoteNode(NODE_ID, str(DEFAULT_EDS_PATH))
    network.add_node(node)
    node.rpdo.read(from_od=True)
    node.tpdo.read(from_od=True)
    return compile_pdos(PdoDirection.RPDO, node.rpdo.map), compile_pdos(PdoDirection.TPDO, node.tpdo.map)


@pytest.fixture(scope="module")
def dbc() -> cantools.database.can.Database:
    return cantools.database.load_file(str(DEFAULT_EDS_PATH.with_name("board.dbc")))


def test_codecs_follow_the_eds_mapping(pdos) -> None:
    rpdos, tpdos = pdos
    sensor = rpdos[1]
    assert sensor.label == "RPDO1 (0x210)"
    assert sensor.names == (
        "motor_encoder_counts",
        "output_encoder_counts",
        "thermistor_adc",
        "motor_current_adc",
    )
    assert sensor.codec.format == "<HHHh" and sensor.length == 8
    assert tpdos[1].cob_id == cob_id(FunctionCode.TPDO1, NODE_ID) and tpdos[1].length == 3
    assert tpdos[8].transmission_type == 10 and not tpdos[8].due_at_sync(9) and tpdos[8].due_at_sync(10)


def test_every_pdo_frame_decodes_with_the_dbc_to_what_was_packed(pdos, dbc) -> None:
    rpdos, tpdos = pdos
    for pdo in (*rpdos.values(), *tpdos.values()):
        if not (pdo.enabled and pdo.names):
            continue
        values = [(i + 1) * 3 if code in "BHhIiQq" else (i + 1) * 0.5 for i, code in enumerate(pdo.formats)]
        frame = pdo.frame(values)
        assert len(frame) == CAN_FRAME_SIZE
        got_id, data = parse_frame(frame)
        assert got_id == pdo.cob_id and len(data) == pdo.length
        decoded = dbc.decode_message(got_id, data, decode_choices=False)  # numbers, not value names
        assert decoded == dict(zip(pdo.names, values, strict=True))
        assert pdo.unpack(data) == tuple(values)
        assert pdo.object_bytes(pdo.names[0], values[0]) == struct.pack("<" + pdo.formats[0], values[0])


def test_a_frame_of_the_wrong_length_does_not_unpack(pdos) -> None:
    _, tpdos = pdos
    with pytest.raises(struct.error):
        tpdos[1].unpack(b"\x01\x02")


def test_layouts_are_equal_by_content_and_hash_alike(pdos) -> None:
    _, tpdos = pdos
    pdo = tpdos[3]
    twin = PdoLayout(
        pdo.direction,
        pdo.number,
        pdo.cob_id,
        pdo.enabled,
        pdo.transmission_type,
        pdo.names,
        pdo.formats,
        pdo.addresses,
    )
    assert twin == pdo and hash(twin) == hash(pdo) and twin is not pdo
    assert PdoLayout(PdoDirection.TPDO, 3, pdo.cob_id, True, 1, ("x",)) != pdo


def test_unpackable_types_are_refused_by_name() -> None:
    class Od:
        STRUCT_TYPES: ClassVar[dict] = {}
        data_type = 0x0009  # VISIBLE_STRING

    class Var:
        name, od, length, index, subindex = "label", Od(), 64, 0x2000, 0

    class Map:
        cob_id, enabled, trans_type, map = TPDO1_ID, True, 1, [Var()]

    with pytest.raises(PdoMappingError, match="TPDO1: label has a data type no PDO codec can pack"):
        compile_pdos(PdoDirection.TPDO, {1: Map()})  # type: ignore[dict-item]


def test_can_frame_limits() -> None:
    assert parse_frame(can_frame(0x7FF, b"\x01")) == (0x7FF, b"\x01")
    with pytest.raises(ValueError, match="11-bit"):
        can_frame(0x800, b"")
    with pytest.raises(ValueError, match="<= 8 bytes"):
        can_frame(0x123, bytes(9))


def test_connection_set_rules() -> None:
    assert [sync_counter(n) for n in (0, 1, 239, 240)] == [1, 2, 240, 1]
    assert [n for n in range(1, 13) if due_at_sync(4, n)] == [4, 8, 12]
    assert not any(due_at_sync(kind, 240) for kind in (0, 254, 255))
    with pytest.raises(ValueError, match="node id"):
        cob_id(FunctionCode.TPDO1, 0)


def test_bus_link_passes_only_the_wanted_standard_data_frames() -> None:
    channel = f"transport-{next(_channels)}"
    with (
        can.Bus(interface="virtual", channel=channel) as ours,
        can.Bus(interface="virtual", channel=channel) as other,
    ):
        notifier = can.Notifier(ours, [], timeout=0.01)
        link = BusLink(ours, notifier, [TPDO1_ID, EMCY_ID])
        unwanted, rpdo1 = cob_id(FunctionCode.TPDO2, NODE_ID), cob_id(FunctionCode.RPDO1, NODE_ID)
        try:
            other.send(can.Message(arbitration_id=unwanted, data=b"\x01", is_extended_id=False))
            other.send(can.Message(arbitration_id=TPDO1_ID, data=b"\x01\x02\x03", is_extended_id=False))
            other.send(can.Message(arbitration_id=TPDO1_ID, is_extended_id=True, data=b"\x09"))
            other.send(can.Message(arbitration_id=EMCY_ID, data=bytes(8), is_extended_id=False))
            assert link.recv(5.0) == (TPDO1_ID, b"\x01\x02\x03")
            assert link.recv(5.0) == (EMCY_ID, bytes(8))
            assert link.recv(0.05) is None
            link.send(can_frame(rpdo1, b"\xaa\xbb"))
            message = other.recv(5.0)
            assert message is not None and (message.arbitration_id, bytes(message.data)) == (
                rpdo1,
                b"\xaa\xbb",
            )
        finally:
            link.close()
            notifier.stop()
