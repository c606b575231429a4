"""SDO frames read back as transfers: the one home of SDO frame decoding for what the rig shows.

`SdoTracker` follows each node's SDO transfers on the default SDO channel (CiA 301: requests on
0x600 + node, answers on 0x580 + node) frame by frame, and says what each frame is: an upload or
a download of index:sub, expedited, segmented (toggle bits checked) or block (sub-blocks put
together as acknowledged, the CRC checked); the value on the frame that completes the transfer;
the abort and its code. `ObjectWords` turns that into a line with the table's names and units
(`hilrig replay --decode`, `hilrig monitor`)::

    tracker = SdoTracker()
    step = tracker.feed(0x590, bytes.fromhex("4b 17 10 00 64 00 00 00"))
    step.describe(words)   # 'SDO upload 0x1017:00 Producer heartbeat time=100 ms from node 0x10 ...'

`parse_abort` is the one reading of an abort frame (the tracker, the log tracer, the SDO client).
"""

from __future__ import annotations

import binascii
import enum
import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from boardproto.cia301 import FunctionCode, SdoAbortCode, SdoCommand, function_of
from hilrig.table import ObjectEntry, RigTable

if TYPE_CHECKING:
    import canopen

SDO_FRAME_BYTES = 8
"""Every SDO frame has 8 data bytes (CiA 301, 7.2.4.3)."""
SHOWN_BYTES = 16
"""A value of no known type shows this many bytes in hex, then how many more."""

# The command specifier: the top three bits of the first byte (CiA 301, 7.2.4.3).
_CS_SHIFT = 5
_CLIENT_DOWNLOAD_SEGMENT, _CLIENT_INITIATE_DOWNLOAD, _CLIENT_INITIATE_UPLOAD = 0, 1, 2
_CLIENT_UPLOAD_SEGMENT, _ABORT, _BLOCK_UPLOAD_CLIENT, _BLOCK_DOWNLOAD_CLIENT = 3, 4, 5, 6
_SERVER_UPLOAD_SEGMENT, _SERVER_DOWNLOAD_SEGMENT, _SERVER_INITIATE_UPLOAD = 0, 1, 2
_SERVER_INITIATE_DOWNLOAD, _BLOCK_DOWNLOAD_SERVER, _BLOCK_UPLOAD_SERVER = 3, 5, 6
# Sub-commands of the block transfers (the low bits of the first byte).
_BLOCK_INITIATE, _BLOCK_END, _BLOCK_ACK, _BLOCK_START = 0, 1, 2, 3
_BLOCK_LAST_SEGMENT = (
    0x80  # c: the last segment of the transfer  # protocol-literal: bit 7 of a segment's first byte
)
_BLOCK_SEQNO_MASK = 0x7F


def value_type_names() -> dict[int, str]:
    """CiA 301 data type code (as canopen and board.toml's DataType number them) -> the name of
    the raw SDO value type that carries it (`hilrig sdo --type`: u8..u64, i8..i64, f32, f64,
    str, bytes)."""
    from canopen.objectdictionary import datatypes as dt

    return {
        dt.BOOLEAN: "u8",
        dt.UNSIGNED8: "u8",
        dt.UNSIGNED16: "u16",
        dt.UNSIGNED32: "u32",
        dt.UNSIGNED64: "u64",
        dt.INTEGER8: "i8",
        dt.INTEGER16: "i16",
        dt.INTEGER32: "i32",
        dt.INTEGER64: "i64",
        dt.REAL32: "f32",
        dt.REAL64: "f64",
        dt.VISIBLE_STRING: "str",
        dt.OCTET_STRING: "bytes",
        dt.UNICODE_STRING: "bytes",
        dt.DOMAIN: "bytes",
    }


class Direction(enum.StrEnum):
    UPLOAD = "upload"  # server -> client: a read
    DOWNLOAD = "download"  # client -> server: a write


class Mode(enum.StrEnum):
    EXPEDITED = "expedited"
    SEGMENTED = "segmented"
    BLOCK = "block"


@dataclass(frozen=True)
class SdoAbortFrame:
    index: int
    subindex: int
    code: int


def parse_abort(data: bytes) -> SdoAbortFrame | None:
    """The object and the code of an abort frame (either direction); None for any other frame."""
    if len(data) != SDO_FRAME_BYTES or data[0] != SdoCommand.ABORT:
        return None
    index, subindex, code = struct.unpack_from("<HBI", data, 1)
    return SdoAbortFrame(index, subindex, code)


def explain_abort(code: int, entry: ObjectEntry | None = None) -> str:
    """'0x06090031 value too high (max 10.0)': the code, its meaning and the table's limit."""
    try:
        words = SdoAbortCode(code).text
    except ValueError:
        words = "unknown abort code"
    text = f"0x{code:08X} {words}"
    if entry is not None:
        if code == SdoAbortCode.VALUE_TOO_HIGH:
            text += f" (max {entry.max})"
        elif code == SdoAbortCode.VALUE_TOO_LOW:
            text += f" (min {entry.min})"
        elif code == SdoAbortCode.VALUE_RANGE_EXCEEDED:
            text += f" (range {entry.min}..{entry.max})"
    return text


def abort_text(abort: SdoAbortFrame, table: RigTable) -> str:
    """'velocity_kp sub 0: 0x06090031 value too high (max 10.0)': the object by the table's name
    and the code in words with the table's limit."""
    entry = table.entry_at(abort.index, abort.subindex)
    where = entry.name if entry is not None else f"0x{abort.index:04X}"
    return f"{where} sub {abort.subindex}: {explain_abort(abort.code, entry)}"


@dataclass(frozen=True)
class SdoStep:
    """What one SDO frame is, in the transfer it belongs to."""

    node: int
    from_server: bool
    direction: Direction | None  # None: a frame that names no transfer (started before the log)
    index: int | None
    subindex: int | None
    mode: Mode | None
    what: str  # the step in words: 'requested', 'segment 2 (7 bytes)', 'done'...
    value: bytes | None = None  # the whole value, on the frame that completes it
    abort: int | None = None
    problem: str | None = None  # a frame out of turn: toggle bit, CRC, size

    def describe(self, words: ObjectWords) -> str:
        """'SDO upload 0x2001:00 velocity_kp=0.2 1/rad from node 0x10 (expedited)'."""
        node = f"node 0x{self.node:02X}"
        if self.direction is Direction.UPLOAD or (self.direction is None and self.from_server):
            peer = f"from {node}"
        else:
            peer = f"by {node}" if self.from_server else f"to {node}"
        block = "block " if self.mode is Mode.BLOCK else ""
        kind = f"SDO {block}{self.direction or 'transfer'}"
        if self.index is None or self.subindex is None:
            text = f"{kind} {self.what} {peer} (its transfer started before the log)"
        elif self.abort is not None:
            who = "the server" if self.from_server else "the client"
            where = words.label(self.index, self.subindex)
            reason = words.abort(self.abort, self.index, self.subindex)
            text = f"{kind} {where} aborted by {who} ({node}): {reason}"
        elif self.value is not None:
            mode = f"{self.mode}, {len(self.value)} byte{'s' if len(self.value) != 1 else ''}"
            detail = f"{mode}{', ' + self.what if self.what else ''}"
            assigned = words.assignment(self.index, self.subindex, self.value)
            text = f"{kind} {assigned} {peer} ({detail})"
        else:
            text = f"{kind} {words.label(self.index, self.subindex)} {self.what} {peer}"
        return f"{text}: {self.problem}" if self.problem else text


@dataclass
class _Transfer:
    direction: Direction
    index: int
    subindex: int
    mode: Mode | None = None
    size: int | None = None
    data: bytearray = field(default_factory=bytearray)
    toggle: int = 0  # the toggle bit the next segment must carry
    segments: int = 0
    last_sent: bool = False  # the frame with the last data went out: the next answer ends it
    crc: bool = False  # block: both sides compute the CRC
    streaming: bool = False  # block: between start (or the initiate answer) and the last ack
    block: dict[int, bytes] = field(default_factory=dict)  # the open sub-block, by sequence number
    last_seqno: int | None = None  # the sequence number of the segment with c set
    value: bytes | None = None  # a download's whole value, once the client sent it all


class SdoTracker:
    """Each node's SDO transfer, followed frame by frame (`feed`). Only what the frames say is
    used: a log that starts in a transfer's middle gives steps without an object."""

    def __init__(self) -> None:
        self._open: dict[int, _Transfer] = {}

    def feed(self, cob_id: int, data: bytes) -> SdoStep | None:
        """The step of one frame; None for a frame that is not on an SDO COB-ID or not 8 bytes."""
        function, node = function_of(cob_id)
        if function not in (FunctionCode.SDO_REQUEST, FunctionCode.SDO_RESPONSE) or node == 0:
            return None
        if len(data) != SDO_FRAME_BYTES:
            return None
        if function == FunctionCode.SDO_REQUEST:
            return self._client(node, bytes(data))
        return self._server(node, bytes(data))

    # --- helpers -----------------------------------------------------------------------
    @staticmethod
    def _step(
        node: int,
        server: bool,
        transfer: _Transfer | None,
        what: str,
        value: bytes | None = None,
        problem: str | None = None,
    ) -> SdoStep:
        if transfer is None:
            return SdoStep(node, server, None, None, None, None, what, value=value, problem=problem)
        return SdoStep(
            node,
            server,
            transfer.direction,
            transfer.index,
            transfer.subindex,
            transfer.mode,
            what,
            value=value,
            problem=problem,
        )

    def _start(self, node: int, direction: Direction, data: bytes, mode: Mode | None = None) -> _Transfer:
        index, subindex = struct.unpack_from("<HB", data, 1)
        transfer = self._open[node] = _Transfer(direction, index, subindex, mode)
        return transfer

    def _end(self, node: int) -> None:
        self._open.pop(node, None)

    def _abort(self, node: int, server: bool, data: bytes) -> SdoStep:
        abort = parse_abort(data)
        assert abort is not None
        transfer = self._open.pop(node, None)
        same = transfer is not None and (transfer.index, transfer.subindex) == (abort.index, abort.subindex)
        return SdoStep(
            node,
            server,
            transfer.direction if same and transfer is not None else None,
            abort.index,
            abort.subindex,
            transfer.mode if same and transfer is not None else None,
            "aborted",
            abort=abort.code,
        )

    def _segmented_part(self, transfer: _Transfer, data: bytes) -> tuple[str | None, int, bool]:
        """A segment of a segmented transfer, either way: its toggle checked, its bytes kept;
        (the toggle's problem or None, the bytes it leaves unused, whether it is the last)."""
        problem = self._toggle(transfer, (data[0] >> 4) & 1)
        transfer.toggle ^= 1
        transfer.segments += 1
        unused, last = (data[0] >> 1) & 0x7, bool(data[0] & 0x1)
        transfer.data += data[1 : SDO_FRAME_BYTES - unused]
        return problem, unused, last

    @staticmethod
    def _toggle(transfer: _Transfer, bit: int) -> str | None:
        if bit != transfer.toggle:
            return f"toggle bit {bit}, expected {transfer.toggle} (not alternated)"
        return None

    @staticmethod
    def _size_problem(transfer: _Transfer, length: int) -> str | None:
        if transfer.size is not None and transfer.size != length:
            return f"{length} bytes, the transfer announced {transfer.size}"
        return None

    def _segment(self, node: int, server: bool, transfer: _Transfer, data: bytes) -> SdoStep:
        """A segment of a block's sub-block: kept until the receiver acknowledges it."""
        seqno = data[0] & _BLOCK_SEQNO_MASK
        transfer.block[seqno] = data[1:]
        last = bool(data[0] & _BLOCK_LAST_SEGMENT)
        if last:
            transfer.last_seqno = seqno
        return self._step(node, server, transfer, f"segment {seqno}{', the last' if last else ''}")

    def _ack(self, node: int, server: bool, transfer: _Transfer, data: bytes) -> SdoStep:
        """The receiver's block acknowledgement: segments 1..ackseq are kept, the rest is sent again."""
        ackseq, blksize = data[1], data[2]
        kept = [transfer.block[n] for n in range(1, ackseq + 1) if n in transfer.block]
        missing = ackseq - len(kept)
        for chunk in kept:
            transfer.data += chunk
        resent = max(transfer.block) - ackseq if transfer.block and max(transfer.block) > ackseq else 0
        ended = transfer.last_seqno is not None and transfer.last_seqno <= ackseq
        transfer.block = {}
        if ended:
            transfer.streaming = False
        else:
            transfer.last_seqno = None  # the last segment was not acknowledged: it comes again
        what = f"block acknowledged up to segment {ackseq}"
        what += f", {resent} to send again" if resent else ""
        what += "" if ended else f", next blocks of {blksize}"
        problem = f"{missing} acknowledged segments were not seen" if missing else None
        return self._step(node, server, transfer, what, problem=problem)

    def _block_end(self, node: int, server: bool, transfer: _Transfer, data: bytes) -> SdoStep:
        """The sender's end of a block transfer: the unused bytes of the last segment and the CRC."""
        unused = (data[0] >> 2) & 0x7
        if unused:
            del transfer.data[-unused:]
        value = bytes(transfer.data)
        sent_crc = struct.unpack_from("<H", data, 1)[0]
        what = ""
        problem = self._size_problem(transfer, len(value))
        if transfer.crc:
            crc = binascii.crc_hqx(value, 0)
            what = f"CRC 0x{sent_crc:04X} ok"
            if crc != sent_crc:
                what, problem = "", f"CRC 0x{sent_crc:04X} does not match the data's 0x{crc:04X}"
        transfer.value = value
        return self._step(node, server, transfer, what, value=value, problem=problem)

    # --- the client's frames (0x600 + node) --------------------------------------------
    def _client(self, node: int, data: bytes) -> SdoStep:
        transfer = self._open.get(node)
        if (
            transfer is not None
            and transfer.streaming
            and transfer.mode is Mode.BLOCK
            and transfer.direction is Direction.DOWNLOAD
        ):
            return self._segment(node, False, transfer, data)
        command = data[0] >> _CS_SHIFT
        if command == _CLIENT_INITIATE_DOWNLOAD:
            expedited_value, size = _initiate(data)
            if expedited_value is not None:
                transfer = self._start(node, Direction.DOWNLOAD, data, Mode.EXPEDITED)
                transfer.value, transfer.last_sent = expedited_value, True
                return self._step(node, False, transfer, "", value=transfer.value)
            transfer = self._start(node, Direction.DOWNLOAD, data, Mode.SEGMENTED)
            transfer.size = size
            size = f"{transfer.size} bytes" if transfer.size is not None else "size not given"
            return self._step(node, False, transfer, f"starts, {size}")
        if command == _CLIENT_DOWNLOAD_SEGMENT:
            if transfer is None or transfer.direction is not Direction.DOWNLOAD:
                return self._step(node, False, None, "segment")
            problem, unused, last = self._segmented_part(transfer, data)
            if last:
                transfer.value, transfer.last_sent = bytes(transfer.data), True
                problem = problem or self._size_problem(transfer, len(transfer.value))
                return self._step(
                    node,
                    False,
                    transfer,
                    f"{transfer.segments} segments",
                    value=transfer.value,
                    problem=problem,
                )
            what = f"segment {transfer.segments} ({SDO_FRAME_BYTES - 1 - unused} bytes)"
            return self._step(node, False, transfer, what, problem=problem)
        if command == _CLIENT_INITIATE_UPLOAD:
            return self._step(node, False, self._start(node, Direction.UPLOAD, data), "requested")
        if command == _CLIENT_UPLOAD_SEGMENT:
            if transfer is None or transfer.direction is not Direction.UPLOAD:
                return self._step(node, False, None, "segment requested")
            problem = self._toggle(transfer, (data[0] >> 4) & 1)
            return self._step(
                node, False, transfer, f"segment {transfer.segments + 1} requested", problem=problem
            )
        if command == _ABORT:
            return self._abort(node, False, data)
        if command == _BLOCK_UPLOAD_CLIENT:
            return self._client_block_upload(node, transfer, data)
        if command == _BLOCK_DOWNLOAD_CLIENT:
            if data[0] & 0x1 == _BLOCK_INITIATE:
                transfer = self._start(node, Direction.DOWNLOAD, data, Mode.BLOCK)
                transfer.crc = bool(data[0] & 0x4)
                transfer.size = struct.unpack_from("<I", data, 4)[0] if data[0] & 0x2 else None
                size = f"{transfer.size} bytes" if transfer.size is not None else "size not given"
                return self._step(
                    node, False, transfer, f"starts, {size}{', with CRC' if transfer.crc else ''}"
                )
            if transfer is None or transfer.mode is not Mode.BLOCK:
                return self._step(node, False, None, "end")
            transfer.last_sent = True
            return self._block_end(node, False, transfer, data)
        return self._step(node, False, transfer, f"command 0x{data[0]:02X} (no CiA 301 client command)")

    def _client_block_upload(self, node: int, transfer: _Transfer | None, data: bytes) -> SdoStep:
        sub = data[0] & 0x3
        if sub == _BLOCK_INITIATE:
            transfer = self._start(node, Direction.UPLOAD, data, Mode.BLOCK)
            transfer.crc = bool(data[0] & 0x4)
            return self._step(node, False, transfer, f"requested, blocks of {data[4]}")
        if transfer is None or transfer.mode is not Mode.BLOCK:
            return self._step(node, False, None, "block upload")
        if sub == _BLOCK_START:
            transfer.streaming = True
            return self._step(node, False, transfer, "start")
        if sub == _BLOCK_ACK:
            return self._ack(node, False, transfer, data)
        self._end(node)  # _BLOCK_END: the client confirms the server's end
        return self._step(node, False, transfer, "done")

    # --- the server's frames (0x580 + node) --------------------------------------------
    def _server(self, node: int, data: bytes) -> SdoStep:
        transfer = self._open.get(node)
        if (
            transfer is not None
            and transfer.streaming
            and transfer.mode is Mode.BLOCK
            and transfer.direction is Direction.UPLOAD
        ):
            return self._segment(node, True, transfer, data)
        command = data[0] >> _CS_SHIFT
        if command == _ABORT:
            return self._abort(node, True, data)
        if command == _SERVER_INITIATE_UPLOAD:
            if transfer is None or transfer.direction is not Direction.UPLOAD:
                transfer = self._start(node, Direction.UPLOAD, data)
            expedited_value, size = _initiate(data)
            if expedited_value is not None:
                transfer.mode = Mode.EXPEDITED
                self._end(node)
                return self._step(node, True, transfer, "", value=expedited_value)
            transfer.mode = Mode.SEGMENTED  # also a block upload the server answers as segmented
            transfer.size = size
            size = f"{transfer.size} bytes" if transfer.size is not None else "size not given"
            return self._step(node, True, transfer, f"starts, {size}")
        if command == _SERVER_UPLOAD_SEGMENT:
            if transfer is None or transfer.direction is not Direction.UPLOAD:
                return self._step(node, True, None, "segment")
            problem, unused, last = self._segmented_part(transfer, data)
            if last:
                self._end(node)
                value = bytes(transfer.data)
                problem = problem or self._size_problem(transfer, len(value))
                return self._step(
                    node, True, transfer, f"{transfer.segments} segments", value=value, problem=problem
                )
            what = f"segment {transfer.segments} ({SDO_FRAME_BYTES - 1 - unused} bytes)"
            return self._step(node, True, transfer, what, problem=problem)
        if command == _SERVER_INITIATE_DOWNLOAD:
            if transfer is None or transfer.direction is not Direction.DOWNLOAD:
                return self._step(
                    node, True, self._answer_without_request(node, Direction.DOWNLOAD, data), "done"
                )
            if transfer.last_sent:  # expedited
                self._end(node)
                return self._step(node, True, transfer, "done")
            return self._step(node, True, transfer, "ready for segments")
        if command == _SERVER_DOWNLOAD_SEGMENT:
            if transfer is None or transfer.direction is not Direction.DOWNLOAD:
                return self._step(node, True, None, "segment confirmed")
            problem = self._toggle_answer(transfer, (data[0] >> 4) & 1)
            if transfer.last_sent:
                self._end(node)
                return self._step(node, True, transfer, "done", problem=problem)
            return self._step(node, True, transfer, f"segment {transfer.segments} confirmed", problem=problem)
        if command == _BLOCK_DOWNLOAD_SERVER:
            if transfer is None or transfer.mode is not Mode.BLOCK:
                return self._step(node, True, None, "block download")
            sub = data[0] & 0x3
            if sub == _BLOCK_INITIATE:
                transfer.streaming = True
                transfer.crc = transfer.crc and bool(data[0] & 0x4)
                return self._step(node, True, transfer, f"ready, blocks of {data[4]}")
            if sub == _BLOCK_ACK:
                return self._ack(node, True, transfer, data)
            self._end(node)  # _BLOCK_END
            return self._step(node, True, transfer, "done")
        if command == _BLOCK_UPLOAD_SERVER:
            if transfer is None or transfer.mode is not Mode.BLOCK:
                return self._step(node, True, None, "block upload")
            if data[0] & 0x1 == _BLOCK_INITIATE:
                transfer.crc = transfer.crc and bool(data[0] & 0x4)
                transfer.size = struct.unpack_from("<I", data, 4)[0] if data[0] & 0x2 else None
                size = f"{transfer.size} bytes" if transfer.size is not None else "size not given"
                return self._step(
                    node, True, transfer, f"starts, {size}{', with CRC' if transfer.crc else ''}"
                )
            return self._block_end(node, True, transfer, data)
        return self._step(node, True, transfer, f"command 0x{data[0]:02X} (no CiA 301 server command)")

    def _answer_without_request(self, node: int, direction: Direction, data: bytes) -> _Transfer:
        index, subindex = struct.unpack_from("<HB", data, 1)
        return _Transfer(direction, index, subindex)

    @staticmethod
    def _toggle_answer(transfer: _Transfer, bit: int) -> str | None:
        """A download segment's answer carries the toggle bit of the segment it confirms."""
        expected = transfer.toggle ^ 1
        return None if bit == expected else f"toggle bit {bit}, expected {expected} (not alternated)"


class ObjectWords:
    """The words of an object and its value: the table's name first (a board field or HIL I/O
    object), then the EDS's (communication objects 0x1000..), else its index. `show(name,
    value)` writes a table entry's value as the caller shows fields elsewhere
    ('velocity_kp=0.2 1/rad')."""

    def __init__(
        self,
        table: RigTable,
        show: Callable[[str, float | int], str],
        od: canopen.ObjectDictionary | None = None,
    ) -> None:
        self.table = table
        self.show = show
        self.od = od

    def _entry(self, index: int, subindex: int) -> ObjectEntry | None:
        return self.table.entry_at(index, subindex)

    def _variable(self, index: int, subindex: int) -> canopen.objectdictionary.ODVariable | None:
        if self.od is None:
            return None
        try:
            return self.od.get_variable(index, subindex)
        except (KeyError, TypeError):
            return None

    def label(self, index: int, subindex: int) -> str:
        """'0x2001:00 velocity_kp', '0x1017:00 Producer heartbeat time', '0x3000:01'."""
        address = f"0x{index:04X}:{subindex:02X}"
        entry = self._entry(index, subindex)
        if entry is not None:
            return f"{address} {entry.name}"
        variable = self._variable(index, subindex)
        return f"{address} {variable.qualname}" if variable is not None else address

    def assignment(self, index: int, subindex: int, value: bytes) -> str:
        """'0x2001:00 velocity_kp=0.2 1/rad': the object and its value decoded by its type."""
        address = f"0x{index:04X}:{subindex:02X}"
        entry = self._entry(index, subindex)
        if entry is not None:
            try:
                number = struct.unpack("<" + entry.data_type.struct_code, value)[0]
            except (ValueError, struct.error):
                return f"{address} {entry.name}={_raw(value)}"
            return f"{address} {self.show(entry.name, number)}"
        variable = self._variable(index, subindex)
        if variable is not None:
            try:
                decoded = variable.decode_raw(value)
            except Exception:  # a length its type does not have: the bytes, as they are
                decoded = value
            unit = f" {variable.unit}" if getattr(variable, "unit", "") else ""
            if isinstance(decoded, bytes | bytearray):
                shown = _raw(bytes(decoded))
            elif isinstance(decoded, str):
                shown = repr(decoded)
            elif isinstance(decoded, float):
                shown = f"{decoded:.6g}"
            elif isinstance(decoded, int) and not unit:
                shown = f"{decoded} (0x{decoded:0{2 * len(value)}X})"
            else:
                shown = str(decoded)
            return f"{address} {variable.qualname}={shown}{unit}"
        if len(value) in (1, 2, 4):
            number = int.from_bytes(value, "little")
            return f"{address}={number} (0x{number:0{2 * len(value)}X})"
        return f"{address}={_raw(value)}"

    def abort(self, code: int, index: int, subindex: int) -> str:
        """'0x06090031 value too high (max 10.0)'."""
        return explain_abort(code, self._entry(index, subindex))


def _initiate(data: bytes) -> tuple[bytes | None, int | None]:
    """An initiate frame that may carry the value (the client's download request, the server's
    upload answer): (the expedited value or None, the size a segmented transfer announces or
    None)."""
    expedited, sized, unused = data[0] & 0x2, data[0] & 0x1, (data[0] >> 2) & 0x3
    if expedited:
        return (data[4 : SDO_FRAME_BYTES - unused] if sized else data[4:]), None
    return None, struct.unpack_from("<I", data, 4)[0] if sized else None


def _raw(value: bytes) -> str:
    shown = value[:SHOWN_BYTES].hex(" ").upper() or "no bytes"
    more = len(value) - SHOWN_BYTES
    return f"{shown} ... ({more} more)" if more > 0 else shown


__all__ = [
    "Direction",
    "Mode",
    "ObjectWords",
    "SdoAbortFrame",
    "SdoStep",
    "SdoTracker",
    "abort_text",
    "explain_abort",
    "parse_abort",
]
