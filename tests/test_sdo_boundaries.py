"""SDO transfers at their boundaries, on the bus with python-canopen's client: the sizes where
end-of-transfer arithmetic goes wrong. A segment carries 7 bytes, so a value of 7k bytes ends on
a full segment (no unused bytes) and one of 7k + 1 on a segment of one byte; a block transfer's
sub-block of blksize segments ends exactly with the value when it is blksize x 7 bytes long.

Uploads read the recorder's DOMAIN (its size is 32 + 4 x samples for one channel, so 1 sample is
36 = 5 x 7 + 1 bytes and 6 samples 56 = 8 x 7); downloads write firmware images into 0x1F50
(60 header bytes + a payload of any length), each checked by the board against its CRC-32."""

from __future__ import annotations

import zlib

import numpy as np
import pytest
from canopen.sdo.client import BlockUploadStream
from conftest import FULL_MAPPING_ON_THE_IDEAL_BUS, TABLE

from boardproto.cia301 import SdoAbortCode
from boardproto.cia302 import (
    FLASH_STATUS_INDEX,
    IMAGE_HEADER_BYTES,
    PROGRAM_DATA_INDEX,
    PROGRAM_NUMBER,
    FlashError,
    ImageHeader,
    ProgramControl,
    flash_error,
)
from boardproto.recording import decode_recording, recording_bytes
from boardproto.table import RecorderObject
from hilrig.apps.capture import CaptureSettings, RecorderClient
from hilrig.errors import SdoAbortError
from hilrig.table import ControlMode
from hilrig.wire import program

pytestmark = pytest.mark.bus

SEGMENT_BYTES = 7


def block_upload(sdo, index: int, blksize: int) -> bytes:
    """A block upload asking for sub-blocks of `blksize` segments (python-canopen asks for 127)."""
    stream_class = type("Blocks", (BlockUploadStream,), {"blksize": blksize})
    stream = stream_class(sdo, index, 0)
    try:
        return bytes(stream.read())
    finally:
        stream.close()


UPLOADS = ((1, 5), (6, 8), (8, 9), (13, 12), (15, 13))
"""(samples, blksize): 36 bytes (a last segment of 1 byte, a second sub-block of it), 56 (a last
segment of 7, one full sub-block), 64 (the largest value the server copies at the initiate
request, 9 x 7 + 1), then two the server streams by offset: 84 (12 x 7, one full sub-block) and
92 (13 x 7 + 1, a second sub-block of one byte)."""


@FULL_MAPPING_ON_THE_IDEAL_BUS
@pytest.mark.requirement("SDO_05")
def test_a_domain_upload_ends_right_at_a_segment_s_and_a_sub_block_s_boundary(make_scenario) -> None:
    # Each recording uploaded three ways: segmented, by block in one sub-block (python-canopen's
    # blksize 127), by block in sub-blocks that end at the boundary. All three the same bytes,
    # of the value's size, and those bytes the velocities the TPDOs carried in the cycles taken.
    rig = make_scenario().rig
    rig.set("control_mode", ControlMode.VELOCITY)
    rig.set("velocity_setpoint", 2.0)
    recorder = RecorderClient(rig.node, TABLE)
    index = recorder.recorder.index_of(RecorderObject.DATA)
    sdo = rig.node.remote.sdo
    for samples, blksize in UPLOADS:
        size = recording_bytes(1, samples)
        recorder.configure(CaptureSettings(channels=("motor_velocity",), samples=samples))
        recorder.arm()
        rig.run(cycles=samples + 2)
        assert recorder.progress().state == "done", samples

        segmented = sdo.upload(index, 0)
        in_one = block_upload(sdo, index, 127)
        in_blocks = block_upload(sdo, index, blksize)
        assert len(segmented) == size, f"a segmented upload of {len(segmented)} bytes, the value has {size}"
        assert in_one == segmented, f"{size} bytes: a block upload in one sub-block gives other bytes"
        assert in_blocks == segmented, f"{size} bytes: a block upload in sub-blocks of {blksize} differs"

        recording = decode_recording(segmented)
        t, velocity = rig.history("motor_velocity")
        by_cycle = dict(zip(np.rint(t / rig.period_s).astype(int).tolist(), velocity.tolist(), strict=True))
        for k in range(samples):
            sent = by_cycle[recording.cycle_of(k) - 1]
            assert recording.column(0)[k] == pytest.approx(sent, rel=1e-6, abs=1e-9), (size, k)


def image_of(payload_bytes: int) -> bytes:
    payload = bytes((7 * k + 3) & 0xFF for k in range(payload_bytes))
    header = ImageHeader(TABLE.board.node.product_code, "0.0.boundary", len(payload), zlib.crc32(payload))
    return header.pack() + payload


DOWNLOADS = (63, 64, 70, 71, 140, 141)
"""Image bytes: 63 = 9 x 7 and 64 = 9 x 7 + 1, 70 and 140 (one and two full sub-blocks: the board
asks for 10 segments at most) and 71 and 141 (one byte into the next). By block download, the
one way 0x1F50 is written (a segmented download of it is refused: unsupported access)."""


@pytest.mark.requirement("FLASH_01", "SDO_05")
def test_an_image_download_ends_right_at_every_segment_and_sub_block_boundary(make_robot) -> None:
    # Each image is taken whole (its CRC-32 checks, the board reports no error); the same image
    # with its last byte changed is refused at the end, with the error the board names.
    module = make_robot(1, trace=False).robot.module(1)
    node = module.node
    sdo = node.remote.sdo

    def download(image: bytes) -> None:
        program.control(node, ProgramControl.STOP)
        program.control(node, ProgramControl.CLEAR)
        node.call_sdo("block download", lambda: _block_download(sdo, image))

    for total in DOWNLOADS:
        image = image_of(total - IMAGE_HEADER_BYTES)
        assert len(image) == total
        download(image)
        status = program.read_u32(node, FLASH_STATUS_INDEX)
        assert status == 0, f"{total} bytes: 0x1F57 = {status:#x}"

        broken = image[:-1] + bytes([image[-1] ^ 0x01])
        with pytest.raises(SdoAbortError) as refused:
            download(broken)
        assert refused.value.abort_code == SdoAbortCode.DATA_CANNOT_BE_STORED, total
        error = flash_error(program.read_u32(node, FLASH_STATUS_INDEX))
        assert error == FlashError.DATA_FORMAT_ERROR, f"{total} bytes, its last byte changed: {error!r}"
    program.control(node, ProgramControl.CLEAR)


def _block_download(sdo, image: bytes) -> None:
    with sdo.open(PROGRAM_DATA_INDEX, PROGRAM_NUMBER, "wb", size=len(image), block_transfer=True) as stream:
        stream.write(image)
