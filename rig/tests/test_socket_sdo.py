"""canopen's SDO client over a raw socket (`hilrig.wire.node.SocketSdoClient`), against canopen's own
SDO server (the fake joint node's LocalNode).

The kernel here may have no CAN, so the client's socket is one end of an AF_UNIX SEQPACKET pair
(the same 16-byte frames, the same system calls); a bridge thread carries its requests onto the
fake node's virtual bus and the node's SDO answers back. On SocketCAN the bus stage runs the same
client against the firmware (the recorder's block upload, every scenario's PDO configuration).
"""

from __future__ import annotations

import socket
import struct
import threading
from collections.abc import Iterator

import can
import canopen
import pytest
from canopen.sdo import SdoAbortedError, SdoClient, SdoCommunicationError

from boardproto.cia301 import SdoAbortCode, sdo_request_cob_id, sdo_response_cob_id
from hilrig.engine.rig import DEFAULT_EDS_PATH
from hilrig.session.fake_node import FakeJointNode
from hilrig.table import RigTable
from hilrig.wire.node import BoardNode, SocketSdoClient, _BoardRemoteNode
from hilrig.wire.transport import CAN_HEADER, RawCanLink, can_frame

OBJECT_DOES_NOT_EXIST = SdoAbortCode.OBJECT_DOES_NOT_EXIST


class Bridge:
    """Frames between the client's socket (`peer` end) and the fake node's virtual bus: every
    frame the client sends goes onto the bus; the node's SDO answers come back while
    `answering` is set."""

    def __init__(self, peer: socket.socket, channel: str, node_id: int) -> None:
        self.peer = peer
        self.bus = can.Bus(interface="virtual", channel=channel)
        self.answer_id = sdo_response_cob_id(node_id)
        self.requests: list[bytes] = []
        self.answering = threading.Event()
        self.answering.set()
        self._stop = threading.Event()
        self._threads = [threading.Thread(target=f, daemon=True) for f in (self._to_bus, self._to_socket)]
        for thread in self._threads:
            thread.start()

    def _to_bus(self) -> None:
        self.peer.settimeout(0.05)
        while not self._stop.is_set():
            try:
                frame = self.peer.recv(16)
            except TimeoutError:
                continue
            if not frame:  # the client's end shut down
                return
            cob_id, length = CAN_HEADER.unpack_from(frame)
            data = frame[8 : 8 + length]
            self.requests.append(data)
            self.bus.send(can.Message(arbitration_id=cob_id, data=data, is_extended_id=False))

    def _to_socket(self) -> None:
        while not self._stop.is_set():
            message = self.bus.recv(0.05)
            if message is not None and message.arbitration_id == self.answer_id and self.answering.is_set():
                self.peer.send(can_frame(message.arbitration_id, bytes(message.data)))

    def close(self) -> None:
        self._stop.set()
        for thread in self._threads:
            thread.join()
        self.bus.shutdown()


@pytest.fixture
def table() -> RigTable:
    return RigTable.load()


@pytest.fixture
def pair() -> Iterator[tuple[socket.socket, socket.socket]]:
    ours, peer = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    try:
        yield ours, peer
    finally:
        ours.close()
        peer.close()


@pytest.fixture
def bridge(pair: tuple[socket.socket, socket.socket], channel: str, fake: FakeJointNode) -> Iterator[Bridge]:
    bridge = Bridge(pair[1], channel, fake.node_id)
    try:
        yield bridge
    finally:
        bridge.close()


@pytest.fixture
def remote(
    pair: tuple[socket.socket, socket.socket], fake: FakeJointNode, bridge: Bridge
) -> canopen.RemoteNode:
    """canopen's RemoteNode as BoardNode makes it on SocketCAN: its SDO client on the socket."""
    node = _BoardRemoteNode(fake.node_id, str(DEFAULT_EDS_PATH), RawCanLink(pair[0]))
    node.sdo.RESPONSE_TIMEOUT = 2.0  # a hang guard: every answer here is in memory
    canopen.Network().add_node(node)  # no bus: the PDO maps want a network, SDO needs none
    return node


def test_the_remote_nodes_sdo_client_and_its_pdo_maps_use_the_socket(remote: canopen.RemoteNode) -> None:
    assert isinstance(remote.sdo, SocketSdoClient)
    assert remote.sdo_channels == [remote.sdo]
    # The PDO maps were built on that client: reading them from the node goes over the socket.
    remote.tpdo.read(from_od=False)
    expected = canopen.RemoteNode(remote.id, str(DEFAULT_EDS_PATH))
    canopen.Network().add_node(expected)
    expected.tpdo.read(from_od=True)
    for number, pdo_map in expected.tpdo.map.items():
        read = remote.tpdo.map[number]
        assert (read.cob_id, read.enabled, read.trans_type) == (
            pdo_map.cob_id,
            pdo_map.enabled,
            pdo_map.trans_type,
        )
        assert [v.name for v in read.map] == [v.name for v in pdo_map.map]


def test_expedited_and_segmented_uploads_and_a_download(
    remote: canopen.RemoteNode, fake: FakeJointNode, bridge: Bridge, table: RigTable
) -> None:
    vendor_id = int.from_bytes(remote.sdo.upload(0x1018, 1), "little")  # expedited
    assert vendor_id == table.board.node.vendor_id
    name = fake.local.sdo[0x1008].raw
    assert len(name) > 4, "a value that needs a segmented transfer"
    assert remote.sdo.upload(0x1008, 0).decode() == name
    index = table.entry("velocity_kp").index
    remote.sdo.download(index, 0, struct.pack("<f", 0.25))
    assert struct.unpack("<f", fake.local.get_data(index, 0))[0] == 0.25
    # The first byte of each request: initiate upload (ccs 2) twice, upload segments (ccs 3)
    # until the name was whole, then an initiate download (ccs 1).
    commands = [request[0] >> 5 for request in bridge.requests]
    assert commands[:3] == [2, 2, 3] and commands[-1] == 1 and set(commands[2:-1]) == {3}


def test_an_abort_from_the_server_is_canopens_sdo_aborted_error(remote: canopen.RemoteNode) -> None:
    with pytest.raises(SdoAbortedError) as raised:
        remote.sdo.upload(0x5FFF, 0)
    assert raised.value.code == OBJECT_DOES_NOT_EXIST


def test_a_silent_server_times_out_and_a_late_answer_is_not_taken_for_the_next(
    remote: canopen.RemoteNode, bridge: Bridge, pair: tuple[socket.socket, socket.socket], table: RigTable
) -> None:
    remote.sdo.RESPONSE_TIMEOUT = 0.05
    bridge.answering.clear()
    with pytest.raises(SdoCommunicationError):
        remote.sdo.upload(0x1018, 1)
    # The answer to that request comes late, after the client gave up (here: a made-up one of
    # another object), and sits in the socket when the next request goes out.
    pair[1].send(can_frame(sdo_response_cob_id(remote.id), bytes([0x43, 0x18, 0x10, 2, 1, 2, 3, 4])))
    bridge.answering.set()
    remote.sdo.RESPONSE_TIMEOUT = 2.0
    assert int.from_bytes(remote.sdo.upload(0x1018, 1), "little") == table.board.node.vendor_id


def test_requests_go_to_the_servers_cob_id(remote: canopen.RemoteNode, bridge: Bridge) -> None:
    sent: list[int] = []
    original = remote.sdo.link.send
    remote.sdo.link.send = lambda frame: (sent.append(CAN_HEADER.unpack_from(frame)[0]), original(frame))[1]  # type: ignore[method-assign]
    remote.sdo.upload(0x1018, 1)
    assert sent == [sdo_request_cob_id(remote.id)]


def test_a_failed_send_is_reported_as_python_can_reports_it(
    remote: canopen.RemoteNode, pair: tuple[socket.socket, socket.socket]
) -> None:
    pair[0].shutdown(socket.SHUT_WR)  # the socket takes no more frames
    with pytest.raises(can.CanOperationError, match="SDO request to 0x6"):
        remote.sdo.upload(0x1018, 1)


def test_a_node_on_any_other_interface_keeps_canopens_own_sdo_client(
    fake: FakeJointNode, channel: str
) -> None:
    bus = can.Bus(interface="virtual", channel=channel)
    node = BoardNode(bus, fake.node_id, None, RigTable.load())
    try:
        assert type(node.remote.sdo) is SdoClient
        assert int.from_bytes(node.upload(0x1018, 1), "little") == RigTable.load().board.node.vendor_id
    finally:
        node.close()
        bus.shutdown()
