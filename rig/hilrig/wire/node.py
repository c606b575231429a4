"""A thin layer over `canopen` for one board node: SDO by field name, NMT, heartbeat, EMCY, PDOs.

The bus is the caller's (a python-can `BusABC`); this module never opens one. PDO frames are
packed and decoded by canopen's own PDO maps, built from the generated EDS (or read back from
the node over SDO), never by hand::

    node = BoardNode(bus, node_id=0x10, eds="build/protocol/board.eds", table=RigTable.load())
    node.read_pdo_configuration(from_node=True)
    node.write("velocity_kp", 0.2)        # SdoAbortError("write velocity_kp: 0x06090031 ...")
    node.nmt(NmtCommand.START)
"""

from __future__ import annotations

import contextlib
import pickle
import struct
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

import can
import canopen
from canopen.emcy import EmcyError
from canopen.pdo import PdoMap
from canopen.sdo import SdoAbortedError, SdoClient, SdoCommunicationError

from boardproto.cia301 import (
    ERROR_BEHAVIOUR_INDEX,
    STANDARD_ID_MASK,
    SYNC_COUNTER_MAX,
    SYNC_COUNTER_OVERFLOW_INDEX,
    ErrorBehaviour,
    NmtCommand,
    NmtState,
    heartbeat_cob_id,
    sdo_response_cob_id,
    split_emcy,
)
from hilrig.errors import IdentityMismatchError, NodeSilentError, SdoAbortError, SdoTimeoutError
from hilrig.table import EmcyCode, ObjectEntry, RigTable
from hilrig.wire.sdo import SDO_FRAME_BYTES, explain_abort, parse_abort
from hilrig.wire.transport import (
    FrameLink,
    PdoDirection,
    PdoLayout,
    RawCanLink,
    can_frame,
    compile_pdos,
    open_link,
    open_raw_socket,
    socketcan_socket,
)

_T = TypeVar("_T")

ObjectDictionary = canopen.ObjectDictionary
"""canopen's object dictionary of a node, as the layers above name it (they import no canopen)."""

RECEIVE_POLL_S = 0.05
"""How often canopen's receive thread wakes up without traffic (bounds the time close() takes)."""
LIVENESS_POLL_S = 0.25
"""How often a wait for the boot-up asks whether the node's process still runs."""


def identity_text(vendor_id: int, product_code: int) -> str:
    """'vendor 0x48494C00 product 0x4A4E5431': a node's or a table's 0x1018 identity."""
    return f"vendor 0x{vendor_id:08X} product 0x{product_code:08X}"


class SocketSdoClient(SdoClient):
    """canopen's SDO client (every transfer, abort, block CRC and retransmission is its code)
    whose frames go over a raw socket (`hilrig.wire.transport`) instead of python-can's `Bus`: a
    request is one system call, and the answers are read on the caller's thread from a socket
    that receives only this server's answers.

    Why: with python-can, every answer became a `Message` in canopen's receive thread and crossed
    to the caller through a queue. That per-frame path bounded SDO in the emulated VM at about
    0.7 ms a frame: the recorder's 64 KiB uploaded by block transfer at ~10 KiB/s, only 2.4x the
    segmented transfer. Over the socket: ~160 KiB/s block, ~14 KiB/s segmented."""

    def __init__(self, rx_cobid: int, tx_cobid: int, od: canopen.ObjectDictionary, link: RawCanLink) -> None:
        super().__init__(rx_cobid, tx_cobid, od)
        self.link = link
        self._batch: bytearray | None = None

    @contextlib.contextmanager
    def batched(self) -> Iterator[None]:
        """Requests are held and sent together (one system call) when an answer is awaited or
        the block ends: a block download's sub-block of up to 127 segments, which no answer
        separates, leaves as one write instead of one per frame."""
        self._batch = bytearray()
        try:
            yield
        finally:
            self._flush()
            self._batch = None

    def _flush(self) -> None:
        if self._batch:
            frames, self._batch = bytes(self._batch), bytearray()
            try:
                self.link.send_frames(frames)
            except OSError as error:
                what = f"SDO requests to 0x{self.rx_cobid:03X} not sent"
                raise can.CanOperationError(f"{what}: {error}") from error

    def on_response(self, can_id: int, data: bytes, timestamp: float) -> None:
        """Answers are read from the socket (`read_response`): the copy canopen's network
        passes on (before its bus is narrowed: `BoardNode.receive_only_answers`) is not kept."""

    def send_request(self, request: bytes | bytearray) -> None:
        if self._batch is not None:
            self._batch += can_frame(self.rx_cobid, bytes(request))
            return
        try:
            self.link.send(can_frame(self.rx_cobid, bytes(request)))
        except OSError as error:  # as python-can's SocketCAN bus reports a failed send
            raise can.CanOperationError(f"SDO request to 0x{self.rx_cobid:03X} not sent: {error}") from error

    def read_response(self) -> bytes:
        """The next answer: SdoAbortedError for an abort frame, SdoCommunicationError when none
        comes within RESPONSE_TIMEOUT (canopen's own contract)."""
        self._flush()
        try:
            frame = self.link.recv(self.RESPONSE_TIMEOUT)
        except OSError as error:  # as python-can's SocketCAN bus reports a failed receive
            raise can.CanOperationError(f"SDO answer from 0x{self.tx_cobid:03X} not read: {error}") from error
        if frame is None:
            raise SdoCommunicationError("No SDO response received")
        response = frame[1]
        abort = parse_abort(response)
        if abort is not None:
            raise SdoAbortedError(abort.code)
        return response

    def request_response(self, sdo_request: bytes | bytearray) -> bytes:
        self._flush()
        # Answers still queued belong to an earlier request (one that timed out, or a block
        # transfer cut short): drop them, as canopen empties its queue here.
        while self.link.recv(0.0) is not None:
            pass
        return super().request_response(sdo_request)

    def close(self) -> None:
        self.link.close()


_TEMPLATE_NODE_ID = 1
_templates: dict[tuple[str, int, int], tuple[bytes, bool]] = {}
_templates_lock = threading.Lock()


def node_dictionary(eds: str | Path, node_id: int) -> canopen.ObjectDictionary:
    """The object dictionary of the EDS at `eds` for node `node_id`, as `canopen.import_od` makes
    it: the file parsed once per process (and per version of it), then a copy for each node (a
    pickle of the parsed one, loaded) with its node-relative values ($NODEID: the COB-IDs) moved
    to `node_id`. Parsing an EDS costs about a hundred such copies, and a robot has a node per
    module."""
    path = Path(eds)
    try:
        stat = path.stat()
    except OSError:
        return canopen.import_od(str(path), node_id)  # canopen's own error for a missing file
    key = (str(path.resolve()), stat.st_mtime_ns, stat.st_size)
    with _templates_lock:
        template = _templates.get(key)
        if template is None:
            parsed = canopen.import_od(str(path), _TEMPLATE_NODE_ID)
            template = _templates[key] = (pickle.dumps(parsed), parsed.node_id is not None)
    od: canopen.ObjectDictionary = pickle.loads(template[0])
    if template[1]:  # the EDS names a node id (DeviceComissioning): this one, as import_od does
        od.node_id = node_id
    shift = node_id - _TEMPLATE_NODE_ID
    if shift:
        for entry in od.values():
            members = entry.subindices.values() if hasattr(entry, "subindices") else (entry,)
            for var in members:
                if var.relative and isinstance(var.default, int):
                    var.default += shift
                if "$NODEID" in (getattr(var, "value_raw", None) or "") and isinstance(var.value, int):
                    var.value += shift
    return od


class _BoardRemoteNode(canopen.RemoteNode):
    """canopen's RemoteNode whose SDO client is a `SocketSdoClient` when an SDO socket is given
    (canopen makes the client inside its constructor, and the PDO maps keep that instance)."""

    def __init__(self, node_id: int, od: canopen.ObjectDictionary | str, sdo_link: RawCanLink | None) -> None:
        self._sdo_link = sdo_link
        super().__init__(node_id, od)

    def add_sdo(self, rx_cobid: int, tx_cobid: int) -> SdoClient:
        if self._sdo_link is None or self.sdo_channels:  # the default channel only
            return super().add_sdo(rx_cobid, tx_cobid)
        client = SocketSdoClient(rx_cobid, tx_cobid, self.object_dictionary, self._sdo_link)
        self.sdo_channels.append(client)  # as canopen's add_sdo (no network yet to subscribe to)
        return client


def answer_filters(node_id: int, bus: can.BusABC, *also: int) -> list[can.typechecking.CanFilter]:
    """Receive filters (python-can's, kernel filters on SocketCAN) for the canopen bus of node
    `node_id` when it needs no PDO from it: the node's heartbeats and, unless its SDO answers
    come on the SDO client's own socket (SocketCAN: `SocketSdoClient`), its SDO answers; plus the
    COB-IDs in `also`."""
    wanted = [heartbeat_cob_id(node_id), *also]
    if socketcan_socket(bus) is None:
        wanted.append(sdo_response_cob_id(node_id))
    return [can.typechecking.CanFilter(can_id=c, can_mask=STANDARD_ID_MASK, extended=False) for c in wanted]


def emcy_object_index(manufacturer: bytes) -> int:
    """The index of the object an EMCY is about: the board puts it in the first two bytes of
    the manufacturer-specific error field (`boardproto.cia301.split_emcy`'s `manufacturer`)."""
    return int.from_bytes(manufacturer[:2], "little")


@dataclass(frozen=True)
class EmcyRecord:
    """An EMCY the node sent, stamped with the lockstep cycle and simulation time it arrived in.
    The one decoder of an EMCY into words: its code's CiA 301 class (canopen's table), the
    board's own name for it (board.toml's [[emcy]]), the register and the object it is about."""

    code: int
    register: int
    data: bytes
    cycle: int
    time_s: float

    @classmethod
    def from_frame(cls, data: bytes, cycle: int = 0, time_s: float = 0.0) -> EmcyRecord:
        """The record of an EMCY frame's data (`boardproto.cia301.split_emcy`)."""
        parts = split_emcy(data)
        return cls(parts.code, parts.register, parts.manufacturer, cycle, time_s)

    @property
    def description(self) -> str:
        """CiA 301's meaning of the code: its error class ('Monitoring', 'Temperature'...)."""
        return EmcyError(self.code, self.register, self.data, 0.0).get_desc()

    @property
    def board_name(self) -> str | None:
        """The board's name for the code (board.toml's [[emcy]] name), None for another code."""
        try:
            return EmcyCode(self.code).name.lower()
        except ValueError:
            return None

    @property
    def object_index(self) -> int:
        """Index of the object the error is about (`emcy_object_index`)."""
        return emcy_object_index(self.data)

    @property
    def summary(self) -> str:
        """The EMCY in words, without when: 'EMCY 0x8130 heartbeat_error (Monitoring) register
        0x11 about 0x1016, bytes 16 10 7f 00 00'."""
        name = self.board_name
        named = f" {name}" if name is not None else ""
        return (
            f"EMCY 0x{self.code:04X}{named} ({self.description}) register 0x{self.register:02X} "
            f"about 0x{self.object_index:04X}, bytes {self.data.hex(' ')}"
        )

    def __str__(self) -> str:
        return f"{self.summary} at t = {self.time_s:.6g} s (cycle {self.cycle})"


TpdoCallback = Callable[[PdoLayout, dict[str, float | int]], None]
"""Called from the receive thread with the TPDO and its decoded values by name."""


class BoardNode:
    """One board on the caller's bus, driven through canopen's RemoteNode.

    Owns a canopen Network (and its receive thread) on `bus`, but not the bus: `close()` stops
    the thread and leaves the bus open for its owner to shut down.
    """

    def __init__(
        self,
        bus: can.BusABC,
        node_id: int,
        eds: str | Path | canopen.ObjectDictionary | None,
        table: RigTable,
        *,
        sdo_timeout_s: float = 1.0,
    ) -> None:
        self.node_id = node_id
        self.table = table
        self.network = canopen.Network(bus)
        if eds is None:  # raw SDO by index needs no dictionary
            eds = canopen.ObjectDictionary()
        # On SocketCAN, SDO answers come on a socket of their own (`SocketSdoClient`).
        sock = socketcan_socket(bus)
        sdo_link = None
        if sock is not None:
            sdo_link = RawCanLink(open_raw_socket(bus.channel, [sdo_response_cob_id(node_id)], beside=sock))
        try:
            self.remote = _BoardRemoteNode(
                node_id,
                eds if isinstance(eds, canopen.ObjectDictionary) else node_dictionary(eds, node_id),
                sdo_link,
            )
        except BaseException:  # e.g. no EDS at that path: nothing left open
            if sdo_link is not None:
                sdo_link.close()
            raise
        self.remote.sdo.RESPONSE_TIMEOUT = sdo_timeout_s
        self.network.add_node(self.remote)
        self.rpdos: dict[int, PdoLayout] = {}
        self.tpdos: dict[int, PdoLayout] = {}
        self.error_behaviour = ErrorBehaviour.PRE_OPERATIONAL
        """What a heartbeat event does to the node's NMT state (0x1029:01), read with the PDOs."""
        self.link: FrameLink | None = None
        """The fast frame link of the per-cycle PDO exchange (`open_link`), None before."""
        self._emcy_callbacks: list[Callable[[EmcyError], None]] = []
        self._tpdo_callbacks: list[TpdoCallback] = []
        self._wired_tpdos: set[int] = set()
        self._heard = threading.Event()
        self._booted = threading.Event()
        self._last_heartbeat: NmtState | None = None
        self._last_heartbeat_at: float | None = None  # time.monotonic() of the latest one
        self.remote.nmt.add_heartbeat_callback(self._on_heartbeat)
        # The receive thread polls the bus this often; close() waits up to one poll.
        self.network.NOTIFIER_CYCLE = RECEIVE_POLL_S
        self.network.connect()  # the bus is given: this only starts canopen's receive thread

    def close(self) -> None:
        """Stop the receive thread and close the frame link; the bus stays open (it is the
        caller's)."""
        if self.link is not None:
            self.link.close()
            self.link = None
        if self.network.notifier is not None:
            self.network.notifier.stop(self.network.NOTIFIER_SHUTDOWN_TIMEOUT)
            self.network.notifier = None
        if isinstance(self.remote.sdo, SocketSdoClient):
            self.remote.sdo.close()

    # --- NMT and heartbeat --------------------------------------------------------------
    def _on_heartbeat(self, state: int) -> None:
        self._last_heartbeat_at = time.monotonic()
        try:
            self._last_heartbeat = NmtState(state)
        except ValueError:
            self._last_heartbeat = None
        self._heard.set()
        if state == NmtState.INITIALISING:
            self._booted.set()

    @property
    def last_heartbeat(self) -> NmtState | None:
        """State in the latest boot-up or heartbeat frame (None before any)."""
        return self._last_heartbeat

    def heartbeat_age_s(self) -> float | None:
        """Wall-clock seconds since the latest boot-up or heartbeat (None before any): a
        heartbeat consumer calls the node lost once this exceeds its consumer time (CiA 301
        1016h), typically a few producer periods. Heartbeats are wall-clock by nature."""
        if self._last_heartbeat_at is None:
            return None
        return time.monotonic() - self._last_heartbeat_at

    def wait_until_alive(self, timeout_s: float, liveness: Callable[[], None] | None = None) -> None:
        """Return once the node has sent a boot-up or heartbeat, or answers an SDO read.

        The boot-up may have gone out before this network listened, and a heartbeat may be
        slow, so after the bound an SDO read of the vendor id is the last chance. `liveness`,
        when given, is called while waiting and raises once the node's process has died: a
        firmware that cannot start is told by its exit and log at once, not by silence at the
        end of the bound.
        """
        deadline = time.monotonic() + timeout_s
        while True:
            left = deadline - time.monotonic()
            if self._heard.wait(max(0.0, min(left, LIVENESS_POLL_S) if liveness is not None else left)):
                return
            if liveness is None:
                break
            liveness()
            if time.monotonic() >= deadline:
                break
        try:
            self.remote.sdo.upload(0x1018, 1)
        except (SdoCommunicationError, SdoAbortedError) as error:
            raise NodeSilentError(
                f"node 0x{self.node_id:02X}: no boot-up or heartbeat within {timeout_s} s and no "
                f"SDO answer ({error}); is the firmware running on this bus with this node id?"
            ) from error

    def nmt(
        self,
        command: NmtCommand,
        *,
        boot_timeout_s: float = 2.0,
        while_booting: Callable[[], object] | None = None,
    ) -> None:
        """Send an NMT command; after a reset, return once the node's boot-up arrived (it comes
        the node's boot time later, the table's [node] boot_ms). `while_booting`, after a reset:
        called once the command is out, before the wait, e.g. to run the SYNC cycles of a
        lockstep node, which counts its boot time in control cycles."""
        resetting = command in (NmtCommand.RESET_NODE, NmtCommand.RESET_COMMUNICATION)
        self._booted.clear()
        self.remote.nmt.send_command(int(command))
        if resetting and while_booting is not None:
            while_booting()
        if resetting and not self._booted.wait(boot_timeout_s):
            raise NodeSilentError(
                f"node 0x{self.node_id:02X}: no boot-up within {boot_timeout_s} s after NMT {command.name}"
            )

    def check_identity(self) -> None:
        """Read 0x1018 vendor id and product code and compare them with board.toml: a node of
        another product is IdentityMismatchError naming both identities."""
        board = self.table.board
        expected = (board.node.vendor_id, board.node.product_code)
        vendor, product = (
            int.from_bytes(self._upload(0x1018, subindex, f"read 0x1018 sub {subindex}"), "little")
            for subindex in (1, 2)
        )
        if (vendor, product) != expected:
            raise IdentityMismatchError(
                f"node 0x{self.node_id:02X}: {identity_text(vendor, product)}, expected "
                f"{identity_text(*expected)} from {board.source}: another device answers on this node id",
                node_id=self.node_id,
                actual=(vendor, product),
                expected=expected,
                table=str(board.source),
            )

    # --- EMCY ---------------------------------------------------------------------------
    def on_emcy(self, callback: Callable[[EmcyError], None]) -> None:
        """Called with canopen's EmcyError for every EMCY frame the node sends: from the driver's
        thread once the frame link is open (`open_link`), from canopen's receive thread before."""
        self._emcy_callbacks.append(callback)
        self.remote.emcy.add_callback(lambda error: None if self.link is not None else callback(error))

    def emcy_received(self, data: bytes) -> None:
        """An EMCY frame that arrived on the frame link: decoded and handed to the callbacks."""
        parts = split_emcy(data)
        error = EmcyError(parts.code, parts.register, parts.manufacturer, time.time())
        for callback in self._emcy_callbacks:
            callback(error)

    # --- SDO by field name --------------------------------------------------------------
    def read(self, name: str) -> float | int:
        """Upload a board field or HIL I/O object by name."""
        entry = self.table.entry(name)
        data = self._upload(entry.index, entry.subindex, f"read {name}", entry)
        return self.remote.object_dictionary.get_variable(entry.index, entry.subindex).decode_raw(data)

    def write(self, name: str, value: float) -> None:
        """Download a value to a board field or HIL I/O object by name (no range check here:
        the node judges, and its refusal comes back as SdoAbortError in words)."""
        entry = self.table.entry(name)
        od = self.remote.object_dictionary.get_variable(entry.index, entry.subindex)
        try:
            data = od.encode_raw(value)
        except struct.error as error:
            raise ValueError(f"write {name}: {value!r} does not fit its type on the bus") from error
        self._call_sdo(
            f"write {name}", entry, lambda: self.remote.sdo.download(entry.index, entry.subindex, data)
        )

    # --- SDO by index ---------------------------------------------------------------
    def upload(self, index: int, subindex: int, what: str | None = None) -> bytes:
        """Upload any object's bytes (segmented when long); a refusal is SdoAbortError in words."""
        what = what or f"read 0x{index:04X}:{subindex:02X}"
        return self._upload(index, subindex, what, self._entry_at(index, subindex))

    def download(self, index: int, subindex: int, data: bytes, what: str | None = None) -> None:
        """Download bytes to any object (segmented when longer than 4)."""
        what = what or f"write 0x{index:04X}:{subindex:02X}"
        self._call_sdo(
            what, self._entry_at(index, subindex), lambda: self.remote.sdo.download(index, subindex, data)
        )

    def _entry_at(self, index: int, subindex: int) -> ObjectEntry | None:
        return self.table.entry_at(index, subindex)

    def block_upload(self, index: int, subindex: int, what: str) -> bytes:
        """Upload by SDO block transfer (CiA 301, with CRC): for large values (a DOMAIN)."""

        def transfer() -> bytes:
            with self.remote.sdo.open(index, subindex, "rb", block_transfer=True) as stream:
                return bytes(stream.read())

        return self._call_sdo(what, None, transfer)

    def _upload(self, index: int, subindex: int, what: str, entry: ObjectEntry | None = None) -> bytes:
        return self._call_sdo(what, entry, lambda: self.remote.sdo.upload(index, subindex))

    def count_sdo_frames(self, on_frame: Callable[[int, int], None] | None) -> None:
        """Call `on_frame(cob_id, dlc)` for each SDO request sent and each answer read on the
        default channel, aborts included (a timed bus charges their bus time: `hilrig.engine.
        bustiming`); None: stop. Wraps the client's own two frame calls, whichever client it is
        (canopen's, or `SocketSdoClient`)."""
        client = self.remote.sdo
        for name in ("send_request", "read_response"):
            client.__dict__.pop(name, None)  # the class's own again
        if on_frame is None:
            return
        send_request, read_response = client.send_request, client.read_response

        def counted_send(request: bytes | bytearray) -> None:
            send_request(request)
            on_frame(client.rx_cobid, len(request))

        def counted_read() -> bytes:
            try:
                response = read_response()
            except SdoAbortedError:
                on_frame(client.tx_cobid, SDO_FRAME_BYTES)
                raise
            on_frame(client.tx_cobid, len(response))
            return response

        client.send_request = counted_send  # type: ignore[method-assign]
        client.read_response = counted_read  # type: ignore[method-assign]

    def call_sdo(self, what: str, transfer: Callable[[], _T]) -> _T:
        """Run canopen SDO traffic (e.g. a `PdoMap.save`); an abort is SdoAbortError in words,
        no answer SdoTimeoutError, each starting with `what`."""
        return self._call_sdo(what, None, transfer)

    def _call_sdo(self, what: str, entry: ObjectEntry | None, transfer: Callable[[], _T]) -> _T:
        try:
            return transfer()
        except SdoAbortedError as error:
            raise SdoAbortError(f"{what}: {explain_abort(error.code, entry)}", error.code) from error
        except SdoCommunicationError as error:
            raise SdoTimeoutError(f"{what}: node 0x{self.node_id:02X} did not answer ({error})") from error

    # --- PDOs ---------------------------------------------------------------------------
    def read_pdo_configuration(self, *, from_node: bool) -> None:
        """Load every PDO's COB-ID, type and mapping into canopen's maps.

        from_node=True reads them over SDO (what the node really does, e.g. after a remap),
        and its error behaviour (0x1029:01) with them; False takes the EDS defaults without bus
        traffic.
        """
        self.error_behaviour = ErrorBehaviour.PRE_OPERATIONAL  # also CiA 301's for a node without 0x1029
        if from_node:
            try:
                raw = self.upload(ERROR_BEHAVIOUR_INDEX, 1, "read error behaviour 0x1029:01")
            except SdoAbortError:
                pass
            else:
                value = int.from_bytes(raw, "little")
                if value in {int(known) for known in ErrorBehaviour}:  # else a profile's own: unknown
                    self.error_behaviour = ErrorBehaviour(value)
        for pdo in (self.remote.rpdo, self.remote.tpdo):
            try:
                pdo.read(from_od=not from_node)
            except SdoAbortedError as error:
                raise SdoAbortError(
                    f"read PDO configuration: {explain_abort(error.code)}", error.code
                ) from error
            except SdoCommunicationError as error:
                raise SdoTimeoutError(f"read PDO configuration: no answer ({error})") from error
        counting = from_node and self._counts_syncs()
        self.rpdos = compile_pdos(PdoDirection.RPDO, self.remote.rpdo.map)
        self.tpdos = compile_pdos(PdoDirection.TPDO, self.remote.tpdo.map, sync_counter=counting)
        for number, pdo_map in self.remote.tpdo.map.items():
            if number not in self._wired_tpdos:  # read() may run again; wire each map once
                pdo_map.add_callback(self._on_tpdo)
                self._wired_tpdos.add(number)

    def _counts_syncs(self) -> bool:
        """Whether the node counts SYNCs (0x1019 != 0), so its TPDOs' start values count; a
        node without 0x1019 does not."""
        try:
            return self.upload(SYNC_COUNTER_OVERFLOW_INDEX, 0, "read 0x1019")[:1] not in (b"", b"\0")
        except SdoAbortError:
            return False

    def on_tpdo(self, callback: TpdoCallback) -> None:
        self._tpdo_callbacks.append(callback)

    def _on_tpdo(self, pdo_map: PdoMap) -> None:
        # Runs in the receive thread right after canopen stored the frame in pdo_map.data;
        # decode now, before the next frame overwrites it.
        if not self._tpdo_callbacks:
            return
        number = next(n for n, m in self.remote.tpdo.map.items() if m is pdo_map)
        values = {var.name: var.raw for var in pdo_map.map}
        layout = self.tpdos[number]
        for callback in self._tpdo_callbacks:
            callback(layout, values)

    def open_link(self, receive_ids: list[int]) -> FrameLink:
        """The frame link for the per-cycle exchange, receiving `receive_ids` (the TPDOs and
        EMCY); a later call (after a remap or a restart) replaces it.

        On SocketCAN it is a raw socket beside the bus, and canopen's bus is narrowed (kernel
        filters) to the SDO answers and heartbeats of this node: canopen's receive thread then
        no longer turns every TPDO into python-can objects. Other interfaces: frames over the
        bus itself, taken from canopen's receive thread.
        """
        bus = self.network.bus
        assert bus is not None
        if self.link is not None:
            self.link.close()
        self.link = open_link(bus, self.network.notifier, receive_ids)
        if socketcan_socket(bus) is not None:
            self.receive_only_answers()
        return self.link

    def receive_only_answers(self) -> None:
        """Narrow canopen's bus to what `answer_filters` lets through (this node's heartbeats,
        and its SDO answers unless they have a socket of their own), for a master that needs no
        PDO from it: on a busy bus every TPDO would otherwise become a python-can object in
        canopen's receive thread, and an SDO answer would queue behind them (on a slow host,
        past the SDO timeout)."""
        bus = self.network.bus
        assert bus is not None
        bus.set_filters(answer_filters(self.node_id, bus))

    def send_frame(self, cob_id: int, data: bytes) -> None:
        """Any raw frame on the node's bus (fault injection: floods, malformed frames)."""
        if self.link is not None:
            self.link.send(can_frame(cob_id, data))
        else:
            self.network.send_message(cob_id, data)

    def await_boot_up(self, start: Callable[[], object], timeout_s: float) -> None:
        """Call `start()` (e.g. start the firmware process) and return once the node's
        boot-up message arrived; NodeSilentError after `timeout_s`."""
        self._booted.clear()
        start()
        if not self._booted.wait(timeout_s):
            raise NodeSilentError(
                f"node 0x{self.node_id:02X}: no boot-up within {timeout_s} s after a restart"
            )

    def send_sync(self, counter: int) -> None:
        if not 1 <= counter <= SYNC_COUNTER_MAX:
            raise ValueError(f"SYNC counter: expected 1..{SYNC_COUNTER_MAX}, got {counter}")
        self.network.sync.transmit(counter)
