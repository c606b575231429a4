"""The bus path itself: two processes exchange frames over a real SocketCAN vcan0, and two
private buses do not see each other's frames. Proves the path before any firmware runs on it."""

from __future__ import annotations

import socket
import subprocess
import sys
from pathlib import Path

import can
import pytest
from bus_echo_peer import ECHO_ANSWER_ID, ECHO_REQUEST_ID, READY_ID

from hilrig.session.buslog import RecorderProcess
from hilrig.session.netns import RECEIVE_QUEUE_BYTES, PrivateBus
from hilrig.wire.transport import RawCanLink, can_frame, open_raw_socket, socketcan_socket

pytestmark = pytest.mark.bus

PEER = Path(__file__).with_name("bus_echo_peer.py")


def _recv_id(bus: can.BusABC, arbitration_id: int, timeout_s: float) -> can.Message:
    # The wait is bounded so a broken path fails instead of hanging; it is not a timing check.
    while True:
        msg = bus.recv(timeout=timeout_s)
        assert msg is not None, f"expected a frame with ID {arbitration_id:#x}, got nothing"
        if msg.arbitration_id == arbitration_id:
            return msg


def test_round_trip_between_two_processes(private_bus: PrivateBus) -> None:
    with private_bus.open() as bus:
        peer = private_bus.popen([sys.executable, str(PEER), private_bus.channel])
        try:
            _recv_id(bus, READY_ID, timeout_s=60.0)
            for n in range(20):
                payload = bytes([n, n + 1, n + 2, 0xAA])
                bus.send(can.Message(arbitration_id=ECHO_REQUEST_ID, data=payload, is_extended_id=False))
                echo = _recv_id(bus, ECHO_ANSWER_ID, timeout_s=10.0)
                assert bytes(echo.data) == bytes(reversed(payload))
            bus.send(can.Message(arbitration_id=0x7FF, data=b"", is_extended_id=False))
            assert peer.wait(timeout=60) == 0
        finally:
            if peer.poll() is None:
                peer.kill()
                peer.wait()


def test_private_buses_are_isolated(private_bus: PrivateBus) -> None:
    with PrivateBus() as other, private_bus.open() as mine, other.open() as theirs:
        theirs.send(can.Message(arbitration_id=0x7B1, data=b"\x01", is_extended_id=False))
        mine.send(can.Message(arbitration_id=0x7B2, data=b"\x02", is_extended_id=False))
        # Our own frame is not echoed back to us (python-can default), so the only frame our
        # socket could ever see here is the other namespace's: it must never arrive.
        assert mine.recv(timeout=0.5) is None
        assert theirs.recv(timeout=0.5) is None


def test_ip_netns_exec_runs_inside_the_namespace(private_bus: PrivateBus) -> None:
    out = subprocess.run(
        private_bus.command(["ip", "-o", "link", "show"]), capture_output=True, text=True, check=True
    ).stdout
    assert "vcan0" in out


def test_the_rigs_sockets_get_a_deep_receive_queue(private_bus: PrivateBus) -> None:
    """A Python reader descheduled on a loaded machine must not lose frames to a full queue."""
    with private_bus.open() as bus:
        granted = bus.socket.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
    assert granted >= RECEIVE_QUEUE_BYTES, f"receive queue {granted} bytes, expected >= {RECEIVE_QUEUE_BYTES}"


def test_the_frame_link_opens_beside_a_bus_in_its_namespace_and_filters(private_bus: PrivateBus) -> None:
    """The raw-socket link (hilrig.wire.transport) lands in the private bus's namespace, not this
    thread's, and the kernel passes it only the COB-IDs it asked for."""
    with private_bus.open() as bus, PrivateBus() as other, other.open() as elsewhere:
        wanted, other_id, sent_id = 0x7C1, 0x7C2, 0x7C3  # no CANopen service's: a bus-level test
        link = RawCanLink(open_raw_socket(private_bus.channel, [wanted], beside=socketcan_socket(bus)))
        try:
            assert link.socket.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF) >= RECEIVE_QUEUE_BYTES
            elsewhere.send(can.Message(arbitration_id=wanted, data=b"\x09", is_extended_id=False))
            for cob_id, data in ((other_id, b"\x01"), (wanted, b"\x02\x03")):
                bus.send(can.Message(arbitration_id=cob_id, data=data, is_extended_id=False))
            assert link.recv(10.0) == (wanted, b"\x02\x03")
            assert link.recv(0.0) is None
            link.send(can_frame(sent_id, b"\xaa"))
            echo = _recv_id(bus, sent_id, timeout_s=10.0)
            assert bytes(echo.data) == b"\xaa"
        finally:
            link.close()


def test_the_recorder_process_logs_every_frame_whole_with_kernel_timestamps(
    private_bus: PrivateBus, tmp_path: Path
) -> None:
    path = tmp_path / "bus.log"
    recorder = RecorderProcess(private_bus, path)
    with private_bus.open() as bus:
        sent = [(0x101 + n, bytes([n] * (n % 9))) for n in range(50)]
        for cob_id, data in sent:
            bus.send(can.Message(arbitration_id=cob_id, data=data, is_extended_id=False))
        bus.send(can.Message(arbitration_id=0x1ABCDEF, data=b"\x01", is_extended_id=True))
    assert recorder.close() == 51
    logged = list(can.LogReader(str(path)))
    assert [(m.arbitration_id, bytes(m.data)) for m in logged[:50]] == sent
    assert logged[50].is_extended_id and logged[50].arbitration_id == 0x1ABCDEF
    stamps = [m.timestamp for m in logged]
    assert stamps == sorted(stamps) and stamps[0] > 1e9  # kernel time, seconds since the epoch
