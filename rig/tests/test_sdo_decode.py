"""SDO frames in words (`hilrig.wire.sdo`): scripted frames of every CiA 301 transfer, expedited,
segmented (toggle bits) and block (sub-blocks, acknowledgements, CRC), both directions, and
aborts; and `hilrig replay --decode` of a log holding them."""

from __future__ import annotations

import binascii
import struct
from pathlib import Path

import can
import pytest

from boardproto.cia301 import FunctionCode, SdoAbortCode, cob_id, sdo_request_cob_id, sdo_response_cob_id
from hilrig import resources
from hilrig.cli import main
from hilrig.table import RigTable
from hilrig.wire.node import node_dictionary
from hilrig.wire.sdo import Direction, Mode, ObjectWords, SdoStep, SdoTracker, abort_text, parse_abort

NODE = 0x10
ABORT = 0x80  # protocol-literal: the abort's command specifier (4 << 5), a byte
REQUEST, ANSWER = sdo_request_cob_id(NODE), sdo_response_cob_id(NODE)
TABLE = RigTable.load()
KP = TABLE.field("velocity_kp")
DEVICE_NAME = 0x1008  # VISIBLE_STRING in the EDS
UNNAMED = 0x5F00  # an index neither the table nor the EDS has


def words() -> ObjectWords:
    od = node_dictionary(resources.DEFAULT_EDS, NODE) if resources.DEFAULT_EDS.is_file() else None
    assert od is not None, f"{resources.DEFAULT_EDS} is not built: make build"
    return ObjectWords(TABLE, lambda name, value: f"{name}={value:.6g} {TABLE.entry(name).unit}", od)


def frame(command: int, index: int = 0, subindex: int = 0, payload: bytes = b"") -> bytes:
    return struct.pack("<BHB", command, index, subindex) + payload.ljust(4, b"\0")


def segment(command: int, data: bytes) -> bytes:
    return bytes([command]) + data.ljust(7, b"\0")


def run(frames: list[tuple[int, bytes]]) -> list[SdoStep]:
    tracker = SdoTracker()
    steps = [tracker.feed(cob_id, data) for cob_id, data in frames]
    assert all(step is not None for step in steps)
    return steps  # type: ignore[return-value]


def texts(frames: list[tuple[int, bytes]]) -> list[str]:
    return [step.describe(words()) for step in run(frames)]


def test_expedited_upload_names_the_field_and_its_value_with_its_unit() -> None:
    lines = texts(
        [
            (REQUEST, frame(0x40, KP.index)),
            (ANSWER, frame(0x43, KP.index, 0, struct.pack("<f", 0.25))),
        ]
    )
    assert lines == [
        f"SDO upload 0x{KP.index:04X}:00 velocity_kp requested from node 0x10",
        f"SDO upload 0x{KP.index:04X}:00 velocity_kp=0.25 {KP.unit} from node 0x10 (expedited, 4 bytes)",
    ]


def test_expedited_download_and_its_confirmation() -> None:
    steps = run(
        [
            (REQUEST, frame(0x23, KP.index, 0, struct.pack("<f", 0.5))),
            (ANSWER, frame(0x60, KP.index)),
        ]
    )
    assert [(s.direction, s.mode, s.from_server) for s in steps] == [
        (Direction.DOWNLOAD, Mode.EXPEDITED, False),
        (Direction.DOWNLOAD, Mode.EXPEDITED, True),
    ]
    lines = [s.describe(words()) for s in steps]
    assert (
        lines[0]
        == f"SDO download 0x{KP.index:04X}:00 velocity_kp=0.5 {KP.unit} to node 0x10 (expedited, 4 bytes)"
    )
    assert lines[1] == f"SDO download 0x{KP.index:04X}:00 velocity_kp done by node 0x10"


def test_expedited_with_fewer_bytes_keeps_only_the_sized_ones() -> None:
    # 0x4B: expedited, size indicated, 2 bytes unused: a UNSIGNED16 (0x1017 heartbeat time)
    (_, answer) = run([(REQUEST, frame(0x40, 0x1017)), (ANSWER, frame(0x4B, 0x1017, 0, b"\x64\x00\xff\xff"))])
    assert answer.value == b"\x64\x00"
    assert answer.describe(words()).startswith("SDO upload 0x1017:00 Producer heartbeat time=100")


def test_an_abort_says_the_code_in_words_with_the_tables_limit() -> None:
    too_high = struct.pack("<f", KP.max * 2)
    lines = texts(
        [
            (REQUEST, frame(0x23, KP.index, 0, too_high)),
            (
                ANSWER,
                frame(ABORT, KP.index, 0, struct.pack("<I", SdoAbortCode.VALUE_TOO_HIGH)),
            ),
        ]
    )
    assert lines[1] == (
        f"SDO download 0x{KP.index:04X}:00 velocity_kp aborted by the server (node 0x10): "
        f"0x06090031 value too high (max {KP.max})"
    )
    # An abort with no transfer seen before it: the object and the code all the same.
    (alone,) = run([(REQUEST, frame(ABORT, UNNAMED, 1, struct.pack("<I", SdoAbortCode.PROTOCOL_TIMED_OUT)))])
    assert alone.describe(words()) == (
        "SDO transfer 0x5F00:01 aborted by the client (node 0x10): 0x05040000 SDO protocol timed out"
    )


def test_parse_abort_is_the_one_reading_of_an_abort_frame() -> None:
    abort = parse_abort(frame(ABORT, KP.index, 0, struct.pack("<I", SdoAbortCode.VALUE_TOO_LOW)))
    assert abort is not None and (abort.index, abort.subindex, abort.code) == (
        KP.index,
        0,
        SdoAbortCode.VALUE_TOO_LOW,
    )
    assert abort_text(abort, TABLE) == f"velocity_kp sub 0: 0x06090032 value too low (min {KP.min})"
    assert parse_abort(frame(0x60, KP.index)) is None
    assert parse_abort(b"\x80\x00") is None


NAME = b"hil-joint-firmware"  # 18 bytes: 7 + 7 + 4


def upload_segments(first_toggle: int = 0, second_toggle: int = 1) -> list[tuple[int, bytes]]:
    return [
        (REQUEST, frame(0x40, DEVICE_NAME)),
        (ANSWER, frame(0x41, DEVICE_NAME, 0, struct.pack("<I", len(NAME)))),
        (REQUEST, segment(0x60 | first_toggle << 4, b"")),
        (ANSWER, segment(0x00 | first_toggle << 4, NAME[0:7])),
        (REQUEST, segment(0x60 | second_toggle << 4, b"")),
        (ANSWER, segment(0x00 | second_toggle << 4, NAME[7:14])),
        (REQUEST, segment(0x60, b"")),
        (ANSWER, segment(0x00 | (3 << 1) | 1, NAME[14:])),  # 3 bytes unused, the last
    ]


def test_segmented_upload_puts_the_segments_together() -> None:
    steps = run(upload_segments())
    assert all(s.problem is None for s in steps), [s.problem for s in steps]
    assert steps[-1].value == NAME and steps[-1].mode is Mode.SEGMENTED
    lines = [s.describe(words()) for s in steps]
    assert lines[1] == "SDO upload 0x1008:00 Manufacturer device name starts, 18 bytes from node 0x10"
    assert lines[3] == "SDO upload 0x1008:00 Manufacturer device name segment 1 (7 bytes) from node 0x10"
    assert lines[-1] == (
        "SDO upload 0x1008:00 Manufacturer device name='hil-joint-firmware' from node 0x10 "
        "(segmented, 18 bytes, 3 segments)"
    )


def test_segmented_upload_with_a_toggle_bit_not_alternated_says_so() -> None:
    steps = run(upload_segments(second_toggle=0))
    assert steps[4].problem == "toggle bit 0, expected 1 (not alternated)"
    assert steps[5].problem == "toggle bit 0, expected 1 (not alternated)"
    assert steps[4].describe(words()).endswith(": toggle bit 0, expected 1 (not alternated)")


def test_segmented_download_of_an_unnamed_object_shows_its_bytes() -> None:
    value = bytes(range(10))
    steps = run(
        [
            (REQUEST, frame(0x21, UNNAMED, 2, struct.pack("<I", len(value)))),
            (ANSWER, frame(0x60, UNNAMED, 2)),
            (REQUEST, segment(0x00, value[:7])),
            (ANSWER, segment(0x20, b"")),
            (REQUEST, segment(0x10 | (4 << 1) | 1, value[7:])),  # toggle 1, 4 unused, the last
            (ANSWER, segment(0x30, b"")),
        ]
    )
    assert all(s.problem is None for s in steps), [s.problem for s in steps]
    lines = [s.describe(words()) for s in steps]
    assert lines[1] == "SDO download 0x5F00:02 ready for segments by node 0x10"
    assert lines[4] == (
        "SDO download 0x5F00:02=00 01 02 03 04 05 06 07 08 09 to node 0x10 (segmented, 10 bytes, 2 segments)"
    )
    assert lines[5] == "SDO download 0x5F00:02 done by node 0x10"


DATA = bytes((7 * n) & 0xFF for n in range(40))  # 6 segments: 5 of 7 bytes, the last of 5


def block_segments(data: bytes, first: int, count: int, last: bool) -> list[bytes]:
    """Segments first..first+count-1 of `data` (7 bytes each), numbered 1.. in their sub-block."""
    out = []
    for n in range(count):
        chunk = data[7 * (first + n) : 7 * (first + n + 1)]
        is_last = last and n == count - 1
        out.append(segment((0x80 if is_last else 0) | (n + 1), chunk))  # protocol-literal: c, bit 7
    return out


def block_upload(crc: int) -> list[tuple[int, bytes]]:
    """Block upload with CRC in sub-blocks of 4: the client acknowledges only 3 of the first
    4 segments, so the 4th comes again as the first of the next sub-block."""
    return [
        (REQUEST, frame(0xA4, UNNAMED, 3, bytes([4, 0]))),  # initiate, CRC supported, blksize 4
        (ANSWER, frame(0xC6, UNNAMED, 3, struct.pack("<I", len(DATA)))),  # CRC, size given
        (REQUEST, segment(0xA3, b"")),  # start
        *((ANSWER, s) for s in block_segments(DATA, 0, 4, last=False)),
        (REQUEST, segment(0xA2, bytes([3, 4]))),  # ack up to 3, next blocks of 4
        *((ANSWER, s) for s in block_segments(DATA, 3, 3, last=True)),
        (REQUEST, segment(0xA2, bytes([3, 4]))),
        (ANSWER, segment(0xC1 | (2 << 2), struct.pack("<H", crc))),  # end: 2 bytes unused
        (REQUEST, segment(0xA1, b"")),  # end confirmed
    ]


def test_block_upload_with_a_resent_segment_and_its_crc() -> None:
    steps = run(block_upload(binascii.crc_hqx(DATA, 0)))
    assert all(s.problem is None for s in steps), [s.problem for s in steps]
    end = steps[-2]
    assert end.value == DATA and end.mode is Mode.BLOCK and end.from_server
    lines = [s.describe(words()) for s in steps]
    assert lines[7] == (
        "SDO block upload 0x5F00:03 block acknowledged up to segment 3, 1 to send again, "
        "next blocks of 4 from node 0x10"
    )
    assert lines[-2].startswith("SDO block upload 0x5F00:03=00 07 0E 15")
    assert lines[-2].endswith(f"from node 0x10 (block, 40 bytes, CRC 0x{binascii.crc_hqx(DATA, 0):04X} ok)")
    assert lines[-1] == "SDO block upload 0x5F00:03 done from node 0x10"


def test_block_upload_with_a_wrong_crc_says_so() -> None:
    right = binascii.crc_hqx(DATA, 0)
    end = run(block_upload(right ^ 0x1234))[-2]
    assert end.problem == f"CRC 0x{right ^ 0x1234:04X} does not match the data's 0x{right:04X}"


def test_block_download_with_crc() -> None:
    crc = binascii.crc_hqx(DATA, 0)
    steps = run(
        [
            (REQUEST, frame(0xC6, UNNAMED, 4, struct.pack("<I", len(DATA)))),  # CRC, size given
            (ANSWER, frame(0xA4, UNNAMED, 4, bytes([127]))),  # CRC, blocks of 127
            *((REQUEST, s) for s in block_segments(DATA, 0, 6, last=True)),
            (ANSWER, segment(0xA2, bytes([6, 127]))),
            (REQUEST, segment(0xC1 | (2 << 2), struct.pack("<H", crc))),
            (ANSWER, segment(0xA1, b"")),
        ]
    )
    assert all(s.problem is None for s in steps), [s.problem for s in steps]
    assert [s.direction for s in steps] == [Direction.DOWNLOAD] * len(steps)
    assert steps[-2].value == DATA and not steps[-2].from_server
    lines = [s.describe(words()) for s in steps]
    assert lines[0] == "SDO block download 0x5F00:04 starts, 40 bytes, with CRC to node 0x10"
    assert lines[2] == "SDO block download 0x5F00:04 segment 1 to node 0x10"
    assert lines[7] == "SDO block download 0x5F00:04 segment 6, the last to node 0x10"
    assert lines[-1] == "SDO block download 0x5F00:04 done by node 0x10"


def test_a_segment_of_a_transfer_before_the_log_is_still_an_sdo_frame() -> None:
    (step,) = run([(ANSWER, segment(0x10, b"abc"))])
    assert step.index is None
    assert (
        step.describe(words()) == "SDO transfer segment from node 0x10 (its transfer started before the log)"
    )


def test_frames_that_are_not_sdo_are_left_alone() -> None:
    tracker = SdoTracker()
    assert tracker.feed(cob_id(FunctionCode.TPDO1, NODE), bytes(8)) is None  # a TPDO
    assert tracker.feed(FunctionCode.SDO_RESPONSE, bytes(8)) is None  # node 0 is no node
    assert tracker.feed(REQUEST, bytes(4)) is None  # an SDO frame has 8 bytes


def test_replay_decode_shows_the_transfers(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "bus.log"
    with can.Logger(str(log)) as logger:
        for n, (cob_id, data) in enumerate(upload_segments() + block_upload(binascii.crc_hqx(DATA, 0))):
            logger(
                can.Message(
                    timestamp=1000.0 + n / 1000, arbitration_id=cob_id, data=data, is_extended_id=False
                )
            )
    assert main(["replay", str(log), "--decode"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 8 + 14
    assert "SDO upload 0x1008:00 Manufacturer device name='hil-joint-firmware' from node 0x10" in out[7]
    assert out[-2].endswith(
        "  0x590  SDO block upload 0x5F00:03=00 07 0E 15 1C 23 2A 31 38 3F 46 4D 54 5B 62 69 ... "
        "(24 more) from node 0x10 (block, 40 bytes, CRC 0xBFAD ok)"
    )
