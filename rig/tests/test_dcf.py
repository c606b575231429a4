"""Parameter sets as DCF (`hilrig.wire.dcf`) between two of canopen's in-process LocalNodes built
from the generated EDS on a virtual bus: which objects count as stored, a DCF saved from one node
and loaded into another (another node id) equals it object for object with its COB-IDs relative
to the node id, PDOs written in CiA 301's order, and a DCF of another product refused."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import can
import canopen
import pytest

from hilrig import resources
from hilrig.table import RigTable
from hilrig.wire.dcf import DcfError, load_dcf, read_dcf, save_dcf, stored_objects

TABLE = RigTable.load()
EDS = resources.eds_for(None)
SOURCE, TARGET = 0x10, 0x11


@pytest.fixture
def network(channel: str) -> Iterator[canopen.Network]:
    if not EDS.exists():
        pytest.skip(f"{EDS} missing: run `make build` first")
    master = canopen.Network(can.Bus(interface="virtual", channel=channel))
    master.connect()
    slaves = canopen.Network(can.Bus(interface="virtual", channel=channel))
    slaves.connect()
    master.slaves = slaves  # type: ignore[attr-defined]
    try:
        yield master
    finally:
        master.disconnect()
        slaves.disconnect()


def board(network: canopen.Network, node_id: int) -> tuple[canopen.LocalNode, canopen.RemoteNode]:
    local = canopen.LocalNode(node_id, canopen.import_od(str(EDS), node_id))
    network.slaves.add_node(local)  # type: ignore[attr-defined]
    remote = canopen.RemoteNode(node_id, canopen.import_od(str(EDS), node_id))
    remote.sdo.RESPONSE_TIMEOUT = 5.0
    network.add_node(remote)
    return local, remote


def test_the_stored_set_is_the_stored_fields_and_the_writable_communication_objects() -> None:
    od = canopen.import_od(str(EDS), SOURCE)
    chosen = {(var.index, var.subindex) for var in stored_objects(od, TABLE)}
    stored_fields = {(field.index, field.subindex) for field in TABLE.board.fields if field.stored}
    assert stored_fields <= chosen
    assert {(0x1017, 0), (0x1005, 0), (0x1400, 1), (0x1600, 0), (0x1A00, 1)} <= chosen
    not_stored = {(field.index, field.subindex) for field in TABLE.board.fields if not field.stored}
    assert not chosen & not_stored
    assert not {key for key in chosen if key[0] in (0x1003, 0x1010, 0x1011, 0x1018)}


def test_a_dcf_saved_from_one_node_loads_into_another_object_for_object(
    network: canopen.Network, tmp_path: Path
) -> None:
    source_local, source = board(network, SOURCE)
    target_local, target = board(network, TARGET)
    kp = TABLE.field("velocity_kp")
    source_local.sdo[kp.index].raw = 0.1875
    source_local.sdo[0x1017].raw = 77
    source_local.sdo[0x1A00][0].raw = 1  # TPDO1 keeps one mapped object: another length

    first = tmp_path / "source.dcf"
    save_dcf(source, TABLE, first)
    text = first.read_text()
    assert "ParameterValue=$NODEID+0x40000180" in text, "TPDO1's COB-ID stays relative to the node id"

    report = load_dcf(target, read_dcf(first, TARGET), TABLE, store=False)
    assert report.verified == report.written == len(stored_objects(target.object_dictionary, TABLE))
    assert target_local.sdo[kp.index].raw == pytest.approx(0.1875)
    assert target_local.sdo[0x1800][1].raw == source_local.sdo[0x1800][1].raw - SOURCE + TARGET
    assert target_local.sdo[0x1A00][0].raw == 1

    second = tmp_path / "target.dcf"
    save_dcf(target, TABLE, second)
    values = [read_dcf(path, SOURCE) for path in (first, second)]
    assert [(v.index, v.subindex, v.value) for v in stored_objects(values[0], TABLE)] == [
        (v.index, v.subindex, v.value) for v in stored_objects(values[1], TABLE)
    ]


def test_a_dcf_of_another_product_is_refused_before_anything_is_written(
    network: canopen.Network, tmp_path: Path
) -> None:
    _, source = board(network, SOURCE)
    target_local, target = board(network, TARGET)
    path = tmp_path / "board.dcf"
    save_dcf(source, TABLE, path)
    path.write_text(path.read_text().replace("ProductNumber=", "ProductNumber=1", 1))
    kp = TABLE.field("velocity_kp")
    before = target_local.sdo[kp.index].raw
    with pytest.raises(DcfError, match="refused, nothing written"):
        load_dcf(target, read_dcf(path, TARGET), TABLE, store=False)
    assert target_local.sdo[kp.index].raw == before
