"""The wire of the per-cycle PDO exchange: codecs compiled from the node's PDO configuration and
the links that carry frames. The only module of the rig that opens raw CAN sockets.

Why not python-can's `Bus` for every frame: its per-frame object and decode cost (its PR #2097
measures ~108 us of CPU per received frame natively) caps a lockstep rig far below what the kernel
and the firmware allow. So on SocketCAN the PDOs (and the node's EMCY) travel over one raw socket
of their own, opened beside the caller's python-can bus (same interface, same network namespace)
with kernel receive filters; `canopen` keeps that bus for NMT and heartbeat only (its SDO client's
frames take a raw socket of their own: `hilrig.wire.node.SocketSdoClient`). On any other
python-can interface (pcan, kvaser, slcan, virtual) the same exchange runs over python-can's `Bus`
(`BusLink`), so a real board keeps working::

    rpdos = compile_pdos(PdoDirection.RPDO, remote.rpdo.map)     # after canopen read them
    link = open_link(bus, notifier, receive_ids=[0x190, 0x290, 0x90])
    link.send(rpdos[1].frame((1200, 300, 2048, 0)))
    cob_id, data = link.recv(0.25) or (None, b"")
"""

from __future__ import annotations

import contextlib
import enum
import fcntl
import functools
import math
import os
import queue
import select
import socket
import struct
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

from boardproto.cia301 import LAST_SYNCHRONOUS_TYPE, STANDARD_ID_MASK, due_at_sync
from hilrig.errors import PdoMappingError
from hilrig.wire import _wire

if TYPE_CHECKING:
    import can
    from canopen.pdo import PdoMap

Value = float | int

CAN_FRAME = struct.Struct("=IB3x8s")
"""struct can_frame of SocketCAN (host byte order): can_id, len, 3 pad bytes, 8 data bytes."""
CAN_HEADER = struct.Struct("=IB3x")
CAN_HEADER_SIZE = CAN_HEADER.size
"""Where a frame's data bytes start."""
CAN_FRAME_SIZE = CAN_FRAME.size
RECEIVE_QUEUE_BYTES = 16 * 1024 * 1024
"""Receive queue of every socket the rig opens: some 20 000 frames (a queued CAN frame costs
about 800 bytes of kernel memory). The default (net.core.rmem_default, about 200 kB: some 250
frames) overflows in half a second when a Python reader is descheduled on a loaded machine, and
the kernel then drops frames without a word."""
LOOK_BEFORE_SLEEP_S = 0.0005
"""The longest a cycle's exchange on a raw socket looks for the next due TPDO before it sleeps in
the kernel (`hilrig.wire._wire`; less, down to not at all, while looking does not pay on that socket):
longer than a node's turnaround in the emulated VM (SYNC to its last TPDO), so
the rig's CPU is not put to sleep and woken between one TPDO and the next, which costs more there
than taking the frame."""
SO_RCVBUFFORCE = getattr(socket, "SO_RCVBUFFORCE", 33)
SO_TIMESTAMP = getattr(socket, "SO_TIMESTAMP", 29)
"""Linux's SO_TIMESTAMP (also the ancillary message type SCM_TIMESTAMP); Python does not name it."""
SO_TIMESTAMPNS = getattr(socket, "SO_TIMESTAMPNS", 35)
"""Linux's SO_TIMESTAMPNS: the kernel's receive time of each frame in nanoseconds (SCM_TIMESTAMPNS)."""
_SIOCGSKNS = 0x894C
"""ioctl: a file descriptor of the network namespace a socket lives in (Linux >= 4.9)."""
_CLONE_NEWNET = 0x40000000


class PdoDirection(enum.StrEnum):
    RPDO = "RPDO"
    TPDO = "TPDO"


@dataclass(frozen=True)
class PdoLayout:
    """One PDO as configured in the node: what it carries, when it is sent, and (when the data
    types are known) its payload codec: `pack`/`unpack`/`frame` with a precompiled `struct`."""

    direction: PdoDirection
    number: int  # 1-based
    cob_id: int
    enabled: bool
    transmission_type: int
    names: tuple[str, ...]  # mapped objects in frame order
    formats: tuple[str, ...] = ()
    """struct code of each mapped object (little-endian, as CANopen); empty: no codec."""
    addresses: tuple[tuple[int, int], ...] = ()
    """(index, subindex) of each mapped object."""
    sync_start: int = 0
    """A TPDO's SYNC start value (sub 6) when the node counts SYNCs (0x1019 != 0): first sent
    at the SYNC whose counter is it (`SyncStarts`); 0: none."""
    codec: struct.Struct = field(init=False, repr=False, compare=False)
    length: int = field(init=False, compare=False)
    """Bytes in the frame, from the mapping."""
    _header: bytes = field(init=False, repr=False, compare=False)
    _padded: struct.Struct = field(init=False, repr=False, compare=False)
    """The codec with the frame's unused data bytes as padding: `frame` packs in one call."""
    _hash: int = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        codec = struct.Struct("<" + "".join(self.formats))
        object.__setattr__(self, "codec", codec)
        object.__setattr__(self, "length", codec.size)
        object.__setattr__(self, "_header", CAN_HEADER.pack(self.cob_id, codec.size))
        padding = "x" * max(0, CAN_FRAME_SIZE - CAN_HEADER.size - codec.size)
        object.__setattr__(self, "_padded", struct.Struct("<" + "".join(self.formats) + padding))
        key = (self.direction, self.number, self.cob_id, self.enabled, self.transmission_type, self.names)
        object.__setattr__(self, "_hash", hash((key, self.formats, self.addresses)))

    def __hash__(self) -> int:  # computed once: layouts key the per-cycle dicts and sets
        return self._hash

    @property
    def label(self) -> str:
        """'TPDO3 (0x390)'."""
        return f"{self.direction.value}{self.number} (0x{self.cob_id:03X})"

    @property
    def is_synchronous(self) -> bool:
        return self.transmission_type <= LAST_SYNCHRONOUS_TYPE

    @property
    def is_cyclic(self) -> bool:
        """Synchronous and sent every n-th SYNC (types 1..240): due at known SYNCs."""
        return self.enabled and 1 <= self.transmission_type <= LAST_SYNCHRONOUS_TYPE

    def due_at_sync(self, sync_number: int) -> bool:
        """True when this TPDO is enabled and due at this SYNC (`cia301.due_at_sync`)."""
        return self.enabled and due_at_sync(self.transmission_type, sync_number)

    # --- Codec --------------------------------------------------------------------------
    def pack(self, values: Sequence[Value]) -> bytes:
        """The payload for `values` in mapping order."""
        return self.codec.pack(*values)

    def pack_named(self, values: Mapping[str, Value]) -> bytes:
        return self.codec.pack(*(values[name] for name in self.names))

    def unpack(self, data: bytes) -> tuple[Value, ...]:
        """Values in mapping order; struct.error when `data` is not exactly `length` bytes."""
        return self.codec.unpack(data)

    def frame(self, values: Sequence[Value]) -> bytes:
        """A whole SocketCAN frame (16 bytes) carrying `values`."""
        return self._header + self._padded.pack(*values)

    def object_bytes(self, name: str, value: Value) -> bytes:
        """How `name` with `value` reads over SDO: the same bytes as in this PDO."""
        return struct.pack("<" + self.formats[self.names.index(name)], value)


_SIZE_EXACT_CODES = {"l": "i", "L": "I"}
"""canopen's struct codes of (UN)SIGNED32 as codes of the same size everywhere: struct reads "<l"
as 4 bytes, numpy (the history's record arrays) as the platform's C long, 8 bytes on Linux."""


def _formats(pdo_map: PdoMap, label: str) -> tuple[str, ...]:
    formats = []
    for var in pdo_map.map:
        try:
            code = var.od.STRUCT_TYPES[var.od.data_type].format.lstrip("<")
            code = _SIZE_EXACT_CODES.get(code, code)
        except KeyError:
            raise PdoMappingError(f"{label}: {var.name} has a data type no PDO codec can pack") from None
        if struct.calcsize("<" + code) * 8 != var.length:
            raise PdoMappingError(f"{label}: {var.name} maps {var.length} bits, its type has another size")
        formats.append(code)
    return tuple(formats)


def compile_pdo(
    direction: PdoDirection, number: int, pdo_map: PdoMap, *, sync_counter: bool = False
) -> PdoLayout:
    """A PdoLayout with its codec from one of canopen's PDO maps (after `pdo.read()`);
    `sync_counter`: the node counts SYNCs (0x1019 != 0), so a TPDO's start value counts."""
    label = f"{direction.value}{number}"
    start = pdo_map.sync_start_value if sync_counter and direction is PdoDirection.TPDO else 0
    return PdoLayout(
        direction=direction,
        number=number,
        cob_id=(pdo_map.cob_id or 0) & STANDARD_ID_MASK,
        enabled=pdo_map.enabled,
        transmission_type=pdo_map.trans_type if pdo_map.trans_type is not None else 255,
        names=tuple(var.name for var in pdo_map.map),
        formats=_formats(pdo_map, label),
        addresses=tuple((var.index, var.subindex) for var in pdo_map.map),
        sync_start=start or 0,
    )


def compile_pdos(
    direction: PdoDirection, maps: Mapping[int, PdoMap], *, sync_counter: bool = False
) -> dict[int, PdoLayout]:
    """Every PDO of one direction, by number."""
    return {
        number: compile_pdo(direction, number, pdo_map, sync_counter=sync_counter)
        for number, pdo_map in maps.items()
    }


def due_table(tpdos: Iterable[PdoLayout]) -> list[frozenset[int]]:
    """The COB-IDs of the cyclic TPDOs due at each SYNC: entry k is the set due at every SYNC
    whose number since the node went operational is k modulo the table's length (the least
    common multiple of their transmission types; one empty entry when none is cyclic). TPDOs
    with a SYNC start value are not in it: `SyncStarts` has them."""
    cyclic = [p for p in tpdos if p.is_cyclic and not p.sync_start]
    period = math.lcm(*(p.transmission_type for p in cyclic)) if cyclic else 1
    return [frozenset(p.cob_id for p in cyclic if p.due_at_sync(k or period)) for k in range(period)]


class SyncStarts:
    """The cyclic TPDOs with a SYNC start value, as the node sends them: after it entered
    operational (`reset`), one goes out first at the SYNC whose counter equals its start value,
    then at every n-th SYNC (n its transmission type), whatever the counter says."""

    def __init__(self, tpdos: Iterable[PdoLayout]) -> None:
        self._pdos = [p for p in tpdos if p.is_cyclic and p.sync_start]
        self._since: dict[int, int] = {}  # COB-ID -> SYNCs since it last went out, once started

    def __bool__(self) -> bool:
        return bool(self._pdos)

    def reset(self) -> None:
        self._since.clear()

    def due(self, counter: int) -> frozenset[int]:
        """The COB-IDs due at the next SYNC, which carries `counter`; call once per SYNC."""
        due = []
        for pdo in self._pdos:
            since = self._since.get(pdo.cob_id)
            if since is None:  # not started: it starts at the SYNC of its counter
                if counter != pdo.sync_start:
                    continue
                since = 0
            else:
                since += 1
                if since < pdo.transmission_type:
                    self._since[pdo.cob_id] = since
                    continue
                since = 0
            due.append(pdo.cob_id)
            self._since[pdo.cob_id] = since
        return frozenset(due)


def can_frame(cob_id: int, data: bytes) -> bytes:
    """One SocketCAN frame (16 bytes) for a standard 11-bit COB-ID."""
    if not 0 <= cob_id <= STANDARD_ID_MASK or len(data) > 8:
        raise ValueError(f"CAN frame: expected an 11-bit id and <= 8 bytes, got 0x{cob_id:X} and {len(data)}")
    return CAN_FRAME.pack(cob_id, len(data), data)


def parse_frame(frame: bytes) -> tuple[int, bytes]:
    """(COB-ID, data) of one SocketCAN frame."""
    cob_id, length, data = CAN_FRAME.unpack(frame)
    return cob_id, data[:length]


# --- Links ------------------------------------------------------------------------------
Frame = tuple[int, bytes]
"""(COB-ID, data) of a received standard data frame."""
Unpack = Callable[[bytes], tuple[Value, ...]]
Decoder = (
    tuple[int, Unpack]
    | tuple[int, Unpack, bytearray, bytearray]
    | tuple[int, Unpack, bytearray, bytearray, bytearray]
)
Decoders = Mapping[int, Decoder]
"""By COB-ID: (length, unpack), or (length, unpack, cycles, payloads) to have each decoded TPDO
also appended to those rows (a PDO's history), tagged with the exchange's cycle (`append_row`),
or (..., arrivals) to have its cycle and arrival time (`ARRIVAL`) appended there too."""
"""COB-ID -> (payload length, unpack) of each TPDO a cycle may wait for."""


class FrameLink(Protocol):
    """Whole frames out and in. `send` takes a SocketCAN frame (`can_frame`, `PdoLayout.frame`);
    `recv(timeout_s)` returns the next received frame that passed the link's filter, or None
    when none arrived within `timeout_s` (0: only what is already there)."""

    def send(self, frame: bytes, /) -> None: ...

    def recv(self, timeout_s: float, /) -> Frame | None: ...

    def close(self) -> None: ...


def send_frames(link: FrameLink, frames: bytes) -> None:
    """Send every 16-byte frame of `frames` (several `can_frame`s joined), in order: one call on
    a raw socket (`RawCanLink.send_frames`), one `send` each on any other link."""
    fast = getattr(link, "send_frames", None)
    if fast is not None:
        fast(frames)
        return
    for offset in range(0, len(frames), CAN_FRAME_SIZE):
        link.send(frames[offset : offset + CAN_FRAME_SIZE])


ROW_CYCLE = struct.Struct("=q")
"""The cycle of a row a decoder carries: a native int64, as `hilrig.wire._wire` appends it."""


append_frame_rows: Callable[[bytes, Mapping[int, tuple[bytearray, bytearray]], int], None] = _wire.append_rows
"""append_frame_rows(frames, rows, cycle): each 16-byte frame of `frames` (several joined) whose
COB-ID has rows in `rows` (COB-ID -> the cycles and payloads `History.row_store` gives) appended
to them as cycle `cycle`'s, payload first, as `append_row` and the C exchange file a TPDO: how a
lockstep cycle files the RPDOs it sent, one call into C (touching no socket: any link)."""


ARRIVAL = struct.Struct("=qq")
"""(cycle, CLOCK_MONOTONIC ns) of a TPDO's arrival, as `hilrig.wire._wire` appends it."""


def append_row(
    decoder: tuple[int, Unpack, bytearray, bytearray] | tuple[int, Unpack, bytearray, bytearray, bytearray],
    cycle: int,
    data: bytes,
    received_ns: int | None = None,
) -> None:
    """Append `data` (a TPDO's payload) as cycle `cycle`'s to the rows a decoder carries (what
    the C exchange does for each TPDO it decodes): the payload first, then the cycle; and with
    a decoder that keeps arrivals, when it came (`received_ns`, default now)."""
    decoder[3].extend(data)
    decoder[2].extend(ROW_CYCLE.pack(cycle))
    if len(decoder) == 5:
        arrived = time.monotonic_ns() if received_ns is None else received_ns
        decoder[4].extend(ARRIVAL.pack(cycle, arrived))


Exchange = Callable[
    [bytes, frozenset[int], Decoders, dict[int, tuple[Value, ...]], float, int | None], Frame | bool | None
]
"""`exchange` bound to one link: (out, due, decoders, got, timeout_s, cycle)."""


def exchanger(link: FrameLink) -> Exchange:
    """`exchange` bound to `link`, for a driver that exchanges every cycle (looked up once): the
    link's own, one call into C on a raw socket, or the frame-by-frame one."""
    fast = getattr(link, "exchange", None)
    return fast if fast is not None else functools.partial(exchange, link)


def exchange(
    link: FrameLink,
    out: bytes,
    due: frozenset[int],
    decoders: Decoders,
    got: dict[int, tuple[Value, ...]],
    timeout_s: float,
    cycle: int | None = None,
) -> Frame | bool | None:
    """One step of a lockstep cycle's exchange: send `out` (joined frames, may be empty), then
    receive. A frame with a COB-ID in `due`, not yet in `got`, of its decoder's length is decoded
    into `got` (and appended to the decoder's rows, if it has any, as `cycle`'s). Returns the
    first frame that is anything else at once (the caller judges it), False when `timeout_s`
    passed with a due COB-ID missing, None when every due COB-ID is in `got` and nothing more is
    queued. On a raw socket all of it is one call into C (`hilrig.wire._wire`); on any other link the
    same, frame by frame."""
    fast = getattr(link, "exchange", None)
    if fast is not None:
        return fast(out, due, decoders, got, timeout_s, cycle)
    send_frames(link, out)
    missing = not due.issubset(got)
    while True:
        frame = link.recv(timeout_s if missing else 0.0)
        if frame is None:
            return False if missing else None
        arrived = time.monotonic_ns()
        cob_id, data = frame
        if cob_id in due and cob_id not in got:
            decoder = decoders.get(cob_id)
            if decoder is not None and len(data) == decoder[0]:
                got[cob_id] = decoder[1](data)
                if len(decoder) >= 4:
                    if cycle is None:
                        raise TypeError("exchange: rows need their cycle")
                    append_row(decoder, cycle, data, arrived)  # type: ignore[arg-type]
                missing = not due.issubset(got)
                continue
        return frame


class RawCanLink:
    """A raw SocketCAN socket: frames in and out without python-can's per-frame objects.

    The socket stays blocking and waits with the kernel's own receive timeout (SO_RCVTIMEO), so
    a receive is one system call (a Python-level timeout would poll first); `recv(0)` asks the
    kernel not to wait (MSG_DONTWAIT)."""

    def __init__(self, sock: socket.socket) -> None:
        self.socket = sock
        sock.settimeout(None)
        # The exchange takes each TPDO's arrival time from the kernel (`hilrig.wire._wire`), not
        # from a clock read a frame: in the bus stage's VM each read is a trapped system call.
        sock.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPNS, 1)
        self._timeout = -1.0
        self._send = sock.send
        self._recv = sock.recv
        self._fd = sock.fileno()

    def _set_timeout(self, timeout_s: float) -> None:
        seconds = int(timeout_s)
        self.socket.setsockopt(
            socket.SOL_SOCKET,
            socket.SO_RCVTIMEO,
            struct.pack("ll", seconds, int((timeout_s - seconds) * 1e6)),
        )
        self._timeout = timeout_s

    def send(self, frame: bytes) -> None:
        self._send(frame)

    def send_frames(self, frames: bytes) -> None:
        """Every 16-byte frame of `frames`, in order, in one call (`hilrig.wire._wire`)."""
        _wire.send_frames(self._fd, frames)

    def exchange(
        self,
        out: bytes,
        due: frozenset[int],
        decoders: Decoders,
        got: dict[int, tuple[Value, ...]],
        timeout_s: float,
        cycle: int | None = None,
    ) -> Frame | bool | None:
        """`transport.exchange` in one call into C (`hilrig.wire._wire.exchange`); a wait for a due
        frame ends after `timeout_s` (the socket's receive timeout)."""
        if timeout_s != self._timeout:
            self._set_timeout(timeout_s)
        return _wire.exchange(self._fd, out, due, decoders, got, LOOK_BEFORE_SLEEP_S, cycle)

    def recv(self, timeout_s: float) -> Frame | None:
        try:
            if timeout_s <= 0.0:
                frame = self._recv(CAN_FRAME_SIZE, socket.MSG_DONTWAIT)
            else:
                if timeout_s != self._timeout:
                    self._set_timeout(timeout_s)
                frame = self._recv(CAN_FRAME_SIZE)
        except (BlockingIOError, TimeoutError):
            return None
        cob_id, length = CAN_HEADER.unpack_from(frame)
        return cob_id, frame[8 : 8 + length]

    def enable_timestamps(self) -> None:
        """Have the kernel stamp every received frame in microseconds, as `receive_stamped`
        reads them (the exchange reads either kind)."""
        self.socket.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMP, 1)

    def receive_stamped(self, max_frames: int) -> list[tuple[int, bytes, float]]:
        """Up to `max_frames` frames already queued, without waiting, oldest first: (raw can_id
        with its EFF/RTR/ERR flags, data, kernel receive time [s since the epoch]) each, taken
        many per system call (`hilrig.wire._wire.receive_stamped`); needs `enable_timestamps()`."""
        return _wire.receive_stamped(self._fd, max_frames)

    def wait_readable(self, timeout_s: float) -> bool:
        """Whether a frame is queued within `timeout_s` (select(2), without taking it)."""
        return bool(select.select([self._fd], [], [], timeout_s)[0])

    def close(self) -> None:
        self.socket.close()


class BusLink:
    """Frames over python-can's `Bus` (any interface), received through the `can.Notifier`
    that already reads that bus (canopen's), filtered by COB-ID into a queue."""

    def __init__(self, bus: can.BusABC, notifier: can.Notifier, receive_ids: Iterable[int]) -> None:
        import can

        self._bus = bus
        self._notifier = notifier
        self._ids = frozenset(receive_ids)
        self._queue: queue.SimpleQueue[Frame] = queue.SimpleQueue()
        self._message = can.Message
        self._listener = _QueueListener(self._queue, self._ids)
        notifier.add_listener(self._listener)

    def send(self, frame: bytes) -> None:
        cob_id, data = parse_frame(frame)
        self._bus.send(self._message(arbitration_id=cob_id, data=data, is_extended_id=False))

    def recv(self, timeout_s: float) -> Frame | None:
        try:
            if timeout_s <= 0.0:
                return self._queue.get_nowait()
            return self._queue.get(timeout=timeout_s)
        except queue.Empty:
            return None

    def close(self) -> None:
        with contextlib.suppress(ValueError):
            self._notifier.remove_listener(self._listener)


class _QueueListener:
    """A can.Listener (duck-typed) that queues the standard data frames with wanted COB-IDs."""

    def __init__(self, sink: queue.SimpleQueue[Frame], ids: frozenset[int]) -> None:
        self._sink = sink
        self._ids = ids

    def on_message_received(self, msg: can.Message) -> None:
        if msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id:
            return
        if msg.arbitration_id in self._ids:
            self._sink.put((msg.arbitration_id, bytes(msg.data)))

    __call__ = on_message_received  # how can.Notifier calls its listeners

    def on_error(self, exc: Exception) -> None:  # python-can's Listener interface
        pass

    def stop(self) -> None:
        pass


def socketcan_socket(bus: can.BusABC) -> socket.socket | None:
    """The kernel socket of a python-can SocketCAN bus (None for any other interface)."""
    sock = getattr(bus, "socket", None)
    channel = getattr(bus, "channel", None)
    if isinstance(sock, socket.socket) and sock.family == socket.AF_CAN and isinstance(channel, str):
        return sock
    return None


def deepen_receive_queue(sock: socket.socket, size: int = RECEIVE_QUEUE_BYTES) -> int:
    """Raise a socket's receive queue to `size` (SO_RCVBUFFORCE as root, else as far as
    net.core.rmem_max allows); returns what the kernel granted."""
    try:
        sock.setsockopt(socket.SOL_SOCKET, SO_RCVBUFFORCE, size)
    except OSError:  # not root: the ceiling is net.core.rmem_max
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, size)
    return sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)


def setns_network(fd: int) -> None:
    """Move the calling thread into the network namespace `fd` refers to."""
    import ctypes

    libc = ctypes.CDLL(None, use_errno=True)
    if libc.setns(fd, _CLONE_NEWNET) != 0:
        err = ctypes.get_errno()
        raise OSError(err, f"setns failed: {os.strerror(err)}")


@contextlib.contextmanager
def _namespace_of(sock: socket.socket | None) -> Iterable[None]:
    """Run the body with the calling thread in the network namespace of `sock` (a socket stays
    in the namespace it was created in, so a private bus's sockets can be matched)."""
    if sock is None:
        yield
        return
    try:
        target = fcntl.ioctl(sock.fileno(), _SIOCGSKNS)
    except OSError:  # an old kernel: the socket's namespace is this thread's, in practice
        yield
        return
    try:
        with open("/proc/thread-self/ns/net", "rb") as home:
            if os.fstat(target).st_ino == os.fstat(home.fileno()).st_ino:
                yield
                return
            setns_network(target)
            try:
                yield
            finally:
                setns_network(home.fileno())
    finally:
        os.close(target)


def open_raw_socket(
    channel: str,
    receive_ids: Iterable[int] | None,
    *,
    beside: socket.socket | None = None,
    timeout_s: float | None = None,
) -> socket.socket:
    """A raw SocketCAN socket on `channel` that receives only standard data frames with
    `receive_ids` (kernel filters; None: every frame), with a deep receive queue; created in the
    network namespace of `beside` (another socket on the same bus, e.g. a private bus's). recv
    raises TimeoutError after `timeout_s` (None: blocking)."""
    ids = sorted(set(receive_ids)) if receive_ids is not None else None
    with _namespace_of(beside):
        sock = socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW)
        try:
            if ids is not None:
                mask = socket.CAN_SFF_MASK | socket.CAN_EFF_FLAG | socket.CAN_RTR_FLAG
                filters = b"".join(struct.pack("=II", cob_id, mask) for cob_id in ids)
                # No id at all: an empty filter list means "receive nothing" to the kernel.
                sock.setsockopt(socket.SOL_CAN_RAW, socket.CAN_RAW_FILTER, filters)
            deepen_receive_queue(sock)
            sock.settimeout(timeout_s)
            sock.bind((channel,))
        except OSError:
            sock.close()
            raise
    return sock


def open_link(bus: can.BusABC, notifier: can.Notifier | None, receive_ids: Iterable[int]) -> FrameLink:
    """The fast link beside `bus`: a raw socket when `bus` is SocketCAN, otherwise frames over
    `bus` itself, received through `notifier` (the one reading it, e.g. canopen's)."""
    ids = list(receive_ids)
    sock = socketcan_socket(bus)
    if sock is not None:
        return RawCanLink(open_raw_socket(bus.channel, ids, beside=sock))
    if notifier is None:
        raise ValueError("a non-SocketCAN bus needs the can.Notifier that reads it")
    return BusLink(bus, notifier, ids)


__all__ = [
    "CAN_FRAME",
    "CAN_FRAME_SIZE",
    "CAN_HEADER",
    "RECEIVE_QUEUE_BYTES",
    "ROW_CYCLE",
    "BusLink",
    "Decoder",
    "Decoders",
    "Exchange",
    "Frame",
    "FrameLink",
    "PdoDirection",
    "PdoLayout",
    "RawCanLink",
    "SyncStarts",
    "Unpack",
    "append_frame_rows",
    "append_row",
    "can_frame",
    "compile_pdo",
    "compile_pdos",
    "deepen_receive_queue",
    "due_table",
    "exchange",
    "exchanger",
    "open_link",
    "open_raw_socket",
    "parse_frame",
    "send_frames",
    "setns_network",
    "socketcan_socket",
]
