"""The PDO codecs compiled from canopen's configuration, the python-can link, and a cycle's
exchange (in C on a raw socket, frame by frame elsewhere), without a kernel bus: a Unix socketpair
carries whole frames as a raw CAN socket does (the raw-socket link is exercised on vcan by
tests/test_bus_smoke.py and every scenario). Frames are
checked against the generated DBC with cantools, independently of the struct codecs."""

from __future__ import annotations

import itertools
import os
import signal
import socket
import struct
import time
from collections.abc import Iterator
from typing import Any, ClassVar

import can
import canopen
import cantools
import pytest

from boardproto.cia301 import SYNC_COB_ID, FunctionCode, cob_id, due_at_sync, emcy_cob_id, sync_counter
from hilrig.engine.history import records_dtype
from hilrig.engine.rig import DEFAULT_EDS_PATH
from hilrig.errors import PdoMappingError
from hilrig.wire import _wire
from hilrig.wire.transport import (
    ARRIVAL,
    CAN_FRAME_SIZE,
    ROW_CYCLE,
    BusLink,
    PdoDirection,
    PdoLayout,
    RawCanLink,
    append_frame_rows,
    can_frame,
    compile_pdos,
    exchange,
    parse_frame,
    send_frames,
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


def test_32_bit_integers_compile_to_codes_of_4_bytes_for_struct_and_numpy() -> None:
    # canopen's struct code for (UN)SIGNED32 is "<l"/"<L": numpy reads "l" as a C long (8
    # bytes), so a history of a TPDO with a CiA 402 INTEGER32 object would come apart.
    node = canopen.RemoteNode(NODE_ID, str(DEFAULT_EDS_PATH))
    objects = node.object_dictionary
    velocity, position = objects["velocity_actual_value"], objects["position_actual_value"]

    class Var:
        def __init__(self, od: Any) -> None:
            self.name, self.od, self.length, self.index, self.subindex = od.name, od, 32, od.index, 0

    class Map:
        cob_id, enabled, trans_type, map = TPDO1_ID, True, 1, [Var(velocity), Var(position)]

    (layout,) = compile_pdos(PdoDirection.TPDO, {1: Map()}).values()  # type: ignore[dict-item]
    assert layout.formats == ("i", "i") and layout.length == 8
    dtype = records_dtype(layout.formats)
    assert dtype.itemsize == 8
    with pytest.raises(ValueError, match="numpy and struct disagree"):
        records_dtype(("l",))


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


# --- One cycle's exchange: in C on a raw socket, frame by frame on any other link ------------
class _FramesOnly:
    """A link with `send`/`recv` alone (as python-can's BusLink): `transport.exchange` runs its
    frame-by-frame version over it."""

    def __init__(self, sock: socket.socket) -> None:
        self._raw = RawCanLink(sock)

    def send(self, frame: bytes) -> None:
        self._raw.send(frame)

    def recv(self, timeout_s: float) -> tuple[int, bytes] | None:
        return self._raw.recv(timeout_s)

    def close(self) -> None:
        self._raw.close()


@pytest.fixture(params=["raw socket (C)", "frame by frame"])
def wire(request: pytest.FixtureRequest) -> Iterator[tuple[Any, socket.socket]]:
    """(the link under test, its peer): a socketpair carries whole 16-byte frames as a raw CAN
    socket does, so the C exchange runs here without a kernel CAN bus."""
    ours, peer = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    link = RawCanLink(ours) if request.param.startswith("raw") else _FramesOnly(ours)
    try:
        yield link, peer
    finally:
        link.close()
        peer.close()


TPDO2_ID, RPDO1_ID = cob_id(FunctionCode.TPDO2, NODE_ID), cob_id(FunctionCode.RPDO1, NODE_ID)
DUE = frozenset({TPDO1_ID, TPDO2_ID})
DECODERS = {TPDO1_ID: (2, struct.Struct("<h").unpack), TPDO2_ID: (4, struct.Struct("<f").unpack)}
SLICE_S = 0.05  # a receive's wait when a due frame is missing (it is, in one test)


def test_arrivals_are_when_each_frame_was_sent_on_the_monotonic_clock(wire) -> None:
    """A decoder that keeps arrivals gets (cycle, CLOCK_MONOTONIC ns) of each TPDO: on a raw
    socket the kernel's receive time (SO_TIMESTAMPNS, which RawCanLink sets; the socketpair
    stamps as CAN does), so a frame that waited in the queue is dated when it came, not when the
    exchange took it."""
    link, peer = wire
    rows = {cob: (bytearray(), bytearray(), bytearray()) for cob in DUE}
    decoders = {cob: (*DECODERS[cob], *rows[cob]) for cob in DUE}
    before = time.monotonic_ns()
    peer.send(can_frame(TPDO1_ID, struct.pack("<h", 5)))
    sent = time.monotonic_ns()
    peer.send(can_frame(TPDO2_ID, struct.pack("<f", 2.0)))
    got: dict[int, tuple] = {}
    assert exchange(link, b"", DUE, decoders, got, SLICE_S, 7) is None
    taken = time.monotonic_ns()
    first = ARRIVAL.unpack(bytes(rows[TPDO1_ID][2]))
    second = ARRIVAL.unpack(bytes(rows[TPDO2_ID][2]))
    assert first[0] == second[0] == 7
    assert before <= first[1] <= second[1] <= taken
    if isinstance(link, RawCanLink):  # the frame-by-frame link reads the clock as it takes each
        assert first[1] <= sent, "dated by the kernel when it was sent, not when it was taken"


def test_exchange_sends_out_then_decodes_every_due_frame(wire) -> None:
    link, peer = wire
    sync = can_frame(SYNC_COB_ID, b"\x01")
    peer.send(can_frame(TPDO2_ID, struct.pack("<f", 1.5)))
    peer.send(can_frame(TPDO1_ID, struct.pack("<h", -3)))
    got: dict[int, tuple] = {}
    assert exchange(link, can_frame(RPDO1_ID, b"\x07") + sync, DUE, DECODERS, got, SLICE_S) is None
    assert got == {TPDO2_ID: (1.5,), TPDO1_ID: (-3,)}
    assert list(got) == [TPDO2_ID, TPDO1_ID]  # arrival order
    assert [parse_frame(peer.recv(CAN_FRAME_SIZE)) for _ in range(2)] == [
        (RPDO1_ID, b"\x07"),
        (SYNC_COB_ID, b"\x01"),
    ]


def test_exchange_hands_back_any_other_frame_at_once_in_arrival_order(wire) -> None:
    link, peer = wire
    for frame in (
        can_frame(TPDO1_ID, b"\x01\x00"),
        can_frame(EMCY_ID, bytes(8)),  # not due
        can_frame(TPDO2_ID, b"\x01\x02"),  # due, of the wrong length
        can_frame(TPDO1_ID, b"\x02\x00"),  # twice
        can_frame(TPDO2_ID, struct.pack("<f", 2.0)),
        can_frame(TPDO2_ID, struct.pack("<f", 3.0)),  # behind the due ones: still handed back
    ):
        peer.send(frame)
    got: dict[int, tuple] = {}
    steps = []
    while (result := exchange(link, b"", DUE, DECODERS, got, SLICE_S)) is not None:
        steps.append(result)
    assert steps == [
        (EMCY_ID, bytes(8)),
        (TPDO2_ID, b"\x01\x02"),
        (TPDO1_ID, b"\x02\x00"),
        (TPDO2_ID, struct.pack("<f", 3.0)),
    ]
    assert got == {TPDO1_ID: (1,), TPDO2_ID: (2.0,)}


def test_exchange_says_false_when_the_wait_passes_with_a_due_frame_missing(wire) -> None:
    link, peer = wire
    peer.send(can_frame(TPDO1_ID, b"\x05\x00"))
    got: dict[int, tuple] = {}
    assert exchange(link, b"", DUE, DECODERS, got, SLICE_S) is False
    assert got == {TPDO1_ID: (5,)}
    peer.send(can_frame(TPDO2_ID, struct.pack("<f", 0.5)))  # the next call goes on where it was
    assert exchange(link, b"", DUE, DECODERS, got, SLICE_S) is None
    assert got == {TPDO1_ID: (5,), TPDO2_ID: (0.5,)}


def test_exchange_with_nothing_due_only_drains_what_is_queued(wire) -> None:
    link, peer = wire
    assert exchange(link, b"", frozenset(), DECODERS, {}, SLICE_S) is None
    peer.send(can_frame(TPDO1_ID, b"\x05\x00"))
    assert exchange(link, b"", frozenset(), DECODERS, {}, SLICE_S) == (TPDO1_ID, b"\x05\x00")
    assert exchange(link, b"", frozenset(), DECODERS, {}, SLICE_S) is None


def test_exchange_appends_each_decoded_frame_to_its_rows_as_the_cycle_s(wire) -> None:
    link, peer = wire
    # Cycle 7's rows already in: the cycles as native int64, the payloads back to back.
    first = {TPDO1_ID: b"\x00\x00", TPDO2_ID: struct.pack("<f", 0.5)}
    rows = {cob: (bytearray(ROW_CYCLE.pack(7)), bytearray(first[cob])) for cob in DUE}
    decoders = {cob: (*DECODERS[cob], *rows[cob]) for cob in DUE}
    for frame in (
        can_frame(TPDO2_ID, b"\x01\x02"),  # wrong length: handed back, in no row
        can_frame(TPDO2_ID, struct.pack("<f", 2.5)),
        can_frame(TPDO1_ID, b"\x09\x00"),
    ):
        peer.send(frame)
    got: dict[int, tuple] = {}
    assert exchange(link, b"", DUE, decoders, got, SLICE_S, 8) == (TPDO2_ID, b"\x01\x02")
    assert exchange(link, b"", DUE, decoders, got, SLICE_S, 8) is None
    cycles_7_8 = ROW_CYCLE.pack(7) + ROW_CYCLE.pack(8)
    assert rows == {
        TPDO1_ID: (cycles_7_8, b"\x00\x00\x09\x00"),
        TPDO2_ID: (cycles_7_8, struct.pack("<ff", 0.5, 2.5)),
    }
    peer.send(can_frame(TPDO1_ID, b"\x01\x00"))
    with pytest.raises(TypeError, match="cycle"):  # rows without a cycle to file them under
        exchange(link, b"", DUE, decoders, {}, SLICE_S)


def test_append_frame_rows_files_each_frame_with_rows_as_the_cycle_s() -> None:
    rpdo2_id = cob_id(FunctionCode.RPDO2, NODE_ID)
    rows = {
        RPDO1_ID: (bytearray(ROW_CYCLE.pack(3)), bytearray(b"\x01\x02")),
        rpdo2_id: (bytearray(), bytearray()),
    }
    frames = can_frame(RPDO1_ID, b"\x05\x06") + can_frame(rpdo2_id, struct.pack("<f", 1.5))
    append_frame_rows(frames + can_frame(SYNC_COB_ID, b"\x04"), rows, 4)  # the SYNC has no rows
    assert rows == {
        RPDO1_ID: (ROW_CYCLE.pack(3) + ROW_CYCLE.pack(4), b"\x01\x02\x05\x06"),
        rpdo2_id: (ROW_CYCLE.pack(4), struct.pack("<f", 1.5)),
    }
    with pytest.raises(ValueError, match="whole 16-byte CAN frames"):
        append_frame_rows(frames[:-1], rows, 5)
    with pytest.raises(TypeError, match="row store"):
        append_frame_rows(frames, {RPDO1_ID: [bytearray(), bytearray()]}, 5)
    assert len(rows[RPDO1_ID][0]) == 2 * ROW_CYCLE.size  # nothing filed by the refused calls


def test_send_frames_sends_each_frame_in_order(wire) -> None:
    link, peer = wire
    frames = [can_frame(RPDO1_ID, bytes([k])) for k in range(5)]
    send_frames(link, b"".join(frames))
    assert [peer.recv(CAN_FRAME_SIZE) for _ in frames] == frames


def test_the_c_exchange_refuses_what_is_not_whole_frames_or_a_socket() -> None:
    ours, peer = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    with ours, peer:
        with pytest.raises(ValueError, match="16-byte"):
            _wire.send_frames(ours.fileno(), b"\x00" * 17)
        with pytest.raises(ValueError, match="16-byte"):
            _wire.exchange(ours.fileno(), b"\x00" * 3, DUE, DECODERS, {}, 0.0)
        with pytest.raises(TypeError, match="due is a set"):
            _wire.exchange(ours.fileno(), b"", list(DUE), DECODERS, {}, 0.0)
    not_a_socket = os.open(os.devnull, os.O_WRONLY)
    try:
        with pytest.raises(OSError):
            _wire.send_frames(not_a_socket, can_frame(SYNC_COB_ID, b""))
    finally:
        os.close(not_a_socket)


def test_a_signal_during_the_c_exchanges_wait_raises_in_python() -> None:
    """Ctrl-C while a cycle waits for a TPDO stops the run, as a Python socket call would."""

    class Interrupted(Exception):
        pass

    def interrupt(signum: int, frame: object) -> None:
        raise Interrupted

    ours, peer = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    link = RawCanLink(ours)
    previous = signal.signal(signal.SIGALRM, interrupt)
    try:
        signal.setitimer(signal.ITIMER_REAL, 0.05)
        with pytest.raises(Interrupted):
            link.exchange(b"", DUE, DECODERS, {}, 60.0)  # would wait a minute for the frames
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
        link.close()
        peer.close()


def test_sync_starts_follow_the_node_start_at_their_counter_then_every_nth() -> None:
    from boardproto.cia301 import FunctionCode, cob_id
    from hilrig.wire.transport import SyncStarts

    def tpdo(node: int, kind: int, start: int) -> PdoLayout:
        tpdo1 = cob_id(FunctionCode.TPDO1, node)
        return PdoLayout(PdoDirection.TPDO, 1, tpdo1, True, kind, ("motor_duty",), ("h",), sync_start=start)

    first, second = cob_id(FunctionCode.TPDO1, 2), cob_id(FunctionCode.TPDO1, 3)
    turns = SyncStarts([tpdo(2, 10, 3), tpdo(3, 10, 4), tpdo(1, 1, 0)])
    assert turns, "two TPDOs take turns"
    counters = [*range(5, 241), *range(1, 30)]  # entered operational at counter 5; 240 wraps to 1
    due = {k: sorted(turns.due(c)) for k, c in enumerate(counters)}
    first_at = counters.index(3, 1)
    assert not any(due[k] for k in range(first_at)), "nothing before counter 3 comes round"
    assert {k: d for k, d in due.items() if d} == {
        first_at: [first],
        first_at + 1: [second],
        first_at + 10: [first],
        first_at + 11: [second],
        first_at + 20: [first],
        first_at + 21: [second],
    }, "then every 10th SYNC"
    turns.reset()
    assert turns.due(13) == frozenset(), "after a reset, each waits for its counter again"


def test_receive_stamped_takes_what_is_queued_in_batches_with_the_kernels_receive_times() -> None:
    """The bus recorder's receive (`RawCanLink.receive_stamped`): every queued frame in arrival
    order, flags kept in the can_id, each with the time the kernel queued it; at most what is
    asked; nothing and no wait when the queue is empty."""
    ours, peer = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    link = RawCanLink(ours)
    link.enable_timestamps()
    try:
        assert link.receive_stamped(10) == []
        assert not link.wait_readable(0.0)
        extended = 0x8000_0000 | 0x1234567
        sent = [(RPDO1_ID, bytes([k % 256] * (k % 9))) for k in range(150)] + [(extended, b"\x01")]
        before = time.time()
        for can_id, data in sent:
            peer.send(struct.pack("=IB3x8s", can_id, len(data), data))
        assert link.wait_readable(0.0)
        first = link.receive_stamped(100)  # more than one recvmmsg batch, less than queued
        rest = link.receive_stamped(1000)
        after = time.time()
        assert [(can_id, data) for can_id, data, _ in first + rest] == sent
        stamps = [stamp for _, _, stamp in first + rest]
        assert before - 1.0 <= stamps[0] <= stamps[-1] <= after + 1.0
        assert stamps == sorted(stamps)
        assert link.receive_stamped(10) == []
    finally:
        link.close()
        peer.close()
    not_a_socket = os.open(os.devnull, os.O_RDONLY)
    try:
        with pytest.raises(OSError):
            _wire.receive_stamped(not_a_socket, 1)
    finally:
        os.close(not_a_socket)
