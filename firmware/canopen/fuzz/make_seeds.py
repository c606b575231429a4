"""Write the hand-made seeds of fuzz_canopen_frames into corpus/frames/ (committed).

Run from anywhere: python3 firmware/canopen/fuzz/make_seeds.py
The byte layout is documented at the top of FrameFuzzer.cpp.
"""

from __future__ import annotations

import binascii
import struct
import sys
import zlib
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "protocol"))  # works without the venv

from boardproto.cia301 import heartbeat_cob_id, sdo_request_cob_id
from boardproto.cia302 import (
    PROGRAM_CONTROL_INDEX,
    PROGRAM_DATA_INDEX,
    PROGRAM_NUMBER,
    ImageHeader,
    ProgramControl,
)
from boardproto.cia305 import (
    FASTSCAN_CONFIRM,
    NODE_ID_UNCONFIGURED,
    LssCommand,
    LssState,
    command_frame,
    fastscan_frame,
)
from boardproto.loader import load_table

NODE_ID = 0x10
NO_REFUSAL = 63  # config byte: refuse no field, storage empty
CONTROL_CLOCK = 0x80  # protocol-literal: a config bit: the heartbeat consumer counts control cycles

# Identifier classes of FrameFuzzer.cpp.
NMT, SYNC, SDO, RPDO1, RPDO2, RPDO3, LSS, RAW_ID = 0, 1, 2, 4, 5, 6, 8, 10
MASTER_ID = 0x01
CONSUMER_HEARTBEAT = 0x1016


def frame(cls: int, data: bytes = b"", dt: int = 0) -> bytes:
    """One record: class, length, time step before it, data."""
    assert len(data) <= 8
    return bytes([(cls << 4) | len(data), dt]) + data


def sdo(*data: int, dt: int = 0) -> bytes:
    return frame(SDO, bytes(data).ljust(8, b"\0"), dt)


def raw(can_id: int, data: bytes = b"", dt: int = 0) -> bytes:
    """A frame on any 11-bit identifier (class 10: the id follows the time step, LE)."""
    assert len(data) <= 8
    return bytes([(RAW_ID << 4) | len(data), dt]) + struct.pack("<H", can_id) + data


def lss(data: bytes, dt: int = 0) -> bytes:
    """An LSS request (class 8: on the master's LSS COB-ID)."""
    return frame(LSS, data, dt)


def master_heartbeat(dt: int = 0) -> bytes:
    return raw(heartbeat_cob_id(MASTER_ID), bytes([0x05]), dt)


def nmt_start() -> bytes:
    return frame(NMT, bytes([0x01, NODE_ID]))


def crc16(data: bytes) -> tuple[int, int]:
    """CRC of SDO block transfer (CiA 301: CCITT 0x1021, initial 0), as its two frame bytes."""
    crc = binascii.crc_hqx(data, 0)
    return crc & 0xFF, crc >> 8


def block_download(index: int, value: bytes, crc_of: bytes | None = None, sub: int = 0) -> bytes:
    """Initiate (CRC, size), one sub-block of segments, end with the CRC of `crc_of`."""
    records = sdo(0xC6, index & 0xFF, index >> 8, sub, *struct.pack("<I", len(value)))
    chunks = [value[i : i + 7] for i in range(0, len(value), 7)]
    for seqno, chunk in enumerate(chunks, start=1):
        last = 0x80 if seqno == len(chunks) else 0  # protocol-literal: block segment's 'no more' bit
        records += sdo(seqno | last, *chunk)
    unused = 7 - len(chunks[-1])
    return records + sdo(0xC1 | (unused << 2), *crc16(value if crc_of is None else crc_of))


def block_upload(index: int, blksize: int, acks: list[int], pst: int = 0) -> bytes:
    """Initiate (CRC), start, one ack per entry of `acks` (ackseq), the client's end."""
    records = sdo(0xA4, index & 0xFF, index >> 8, 0x00, blksize, pst) + sdo(0xA3)
    for ackseq in acks:
        records += sdo(0xA2, ackseq, blksize)
    return records + sdo(0xA1)


# The field recorder's objects (board.toml [recorder], index 0x3200): state, channels, samples,
# trigger, data; and the values the seeds write.
RECORDER_STATE, RECORDER_CHANNELS, RECORDER_SAMPLES, RECORDER_TRIGGER, RECORDER_DATA = (
    0x3200,
    0x3201,
    0x3203,
    0x3204,
    0x3206,
)
ARMED, IDLE = 1, 0
LEVEL, RISING = 1, 0


def download(index: int, sub: int, value: int, size: int) -> bytes:
    """Expedited download of `size` bytes."""
    command = 0x23 | ((4 - size) << 2)
    return sdo(command, index & 0xFF, index >> 8, sub, *value.to_bytes(size, "little").ljust(4, b"\0"))


def recorder_recording(samples: int, trigger_level: float | None = None) -> bytes:
    """Records motor_velocity and velocity_setpoint for `samples` samples, operational, one SYNC a
    cycle; with a level, a rising trigger on velocity_setpoint (changed by SDO halfway)."""
    records = download(RECORDER_CHANNELS, 1, 0x2100, 2) + download(RECORDER_CHANNELS, 2, 0x2401, 2)
    records += download(RECORDER_CHANNELS, 0, 2, 1) + download(RECORDER_SAMPLES, 0, samples, 4)
    if trigger_level is not None:
        level = int.from_bytes(struct.pack("<f", trigger_level), "little")
        records += download(RECORDER_TRIGGER, 1, LEVEL, 1) + download(RECORDER_TRIGGER, 2, 0x2401, 2)
        records += download(RECORDER_TRIGGER, 3, level, 4) + download(RECORDER_TRIGGER, 4, RISING, 1)
        records += download(RECORDER_TRIGGER, 6, 50, 1)
    records += nmt_start() + download(RECORDER_STATE, 0, ARMED, 1)
    for cycle in range(2 * samples):
        if trigger_level is not None and cycle == samples:
            records += sdo(0x23, 0x01, 0x24, 0x00, *struct.pack("<f", trigger_level + 1.0))
        records += frame(SYNC, dt=125)
    return records


def program_download(product_code: int, payload: bytes) -> bytes:
    """0x1F51 stop and clear, the image (header + payload) into 0x1F50:01 in one sub-block, start."""
    header = ImageHeader(product_code, "9.9.9", len(payload), zlib.crc32(payload))
    records = download(PROGRAM_CONTROL_INDEX, PROGRAM_NUMBER, ProgramControl.STOP, 1)
    records += download(PROGRAM_CONTROL_INDEX, PROGRAM_NUMBER, ProgramControl.CLEAR, 1)
    records += block_download(PROGRAM_DATA_INDEX, header.pack() + payload, sub=PROGRAM_NUMBER)
    return records + download(PROGRAM_CONTROL_INDEX, PROGRAM_NUMBER, ProgramControl.START, 1)


def seeds() -> dict[str, bytes]:
    table = Path(__file__).resolve().parents[3] / "protocol" / "board.toml"
    product_code = load_table(table).node.product_code
    upload_1008 = sdo(0x40, 0x08, 0x10, 0x00)
    segments = b"".join(sdo(0x60 | (0x10 * (n % 2))) for n in range(3))
    velocity = struct.pack("<f", 1.5)
    return {
        "sdo_expedited_upload_1000": bytes([NO_REFUSAL]) + sdo(0x40, 0x00, 0x10, 0x00),
        "sdo_segmented_upload_1008": bytes([NO_REFUSAL]) + upload_1008 + segments,
        "sdo_expedited_download_2401": bytes([NO_REFUSAL]) + sdo(0x23, 0x01, 0x24, 0x00, *velocity),
        "sdo_segmented_download_2401": bytes([NO_REFUSAL])
        + sdo(0x21, 0x01, 0x24, 0x00, 4)
        + sdo(0x00 | (3 << 1) | 0x01, *velocity),
        "sdo_upload_timeout": bytes([NO_REFUSAL]) + upload_1008 + sdo(0x60, dt=0xFF),
        "nmt_start": bytes([NO_REFUSAL]) + nmt_start(),
        "sync_operational": bytes([NO_REFUSAL]) + nmt_start() + frame(SYNC, dt=100) + frame(SYNC, dt=100),
        "rpdo_setpoints_then_sync": bytes([NO_REFUSAL])
        + nmt_start()
        + frame(RPDO1, struct.pack("<HHHh", 1000, 2000, 2048, -500))
        + frame(RPDO2, velocity + struct.pack("<f", 2.0))
        + frame(RPDO3, struct.pack("<ff", 1.0, 0.25))
        + frame(SYNC, dt=125),
        # Regression: 0x1005 = 0x600+id once turned every later SDO request into a SYNC.
        "sync_cob_id_on_sdo_request": bytes([NO_REFUSAL])
        + sdo(0x23, 0x05, 0x10, 0x00, sdo_request_cob_id(NODE_ID) & 0xFF, sdo_request_cob_id(NODE_ID) >> 8)
        + sdo(0x40, 0x00, 0x10, 0x00),
        # Block transfer: whole exchanges the fuzzer can then cut, repeat and corrupt.
        "sdo_block_download_2401": bytes([NO_REFUSAL]) + block_download(0x2401, velocity),
        "sdo_block_download_2401_wrong_crc": bytes([NO_REFUSAL])
        + block_download(0x2401, velocity, crc_of=b"\x00" + velocity[1:]),
        "sdo_block_download_past_the_object": bytes([NO_REFUSAL])
        + sdo(0xC4, 0x01, 0x24, 0x00)  # size not indicated
        + sdo(0x01, *b"1234567")
        + sdo(0x81, *b"89"),
        "sdo_block_upload_1008": bytes([NO_REFUSAL]) + block_upload(0x1008, 127, [3]),
        # blksize 1: a sub-block per segment; ack 0 asks for the first one again.
        "sdo_block_upload_1008_repeat": bytes([NO_REFUSAL]) + block_upload(0x1008, 1, [0, 1, 1, 1]),
        "sdo_block_upload_1008_pst_fallback": bytes([NO_REFUSAL])
        + sdo(0xA4, 0x08, 0x10, 0x00, 127, 18)
        + segments,
        "sdo_block_upload_timeout": bytes([NO_REFUSAL])
        + sdo(0xA4, 0x08, 0x10, 0x00, 127)
        + sdo(0xA3)
        + sdo(0xA2, 3, 127, dt=0xFF),
        # Field recorder: a recording, its upload by block, by segments, refused while armed.
        "recorder_immediate_block_upload": bytes([NO_REFUSAL])
        + recorder_recording(6)
        + block_upload(RECORDER_DATA, 127, [12]),
        "recorder_level_trigger_segmented_upload": bytes([NO_REFUSAL])
        + recorder_recording(8, trigger_level=2.0)
        + sdo(0x40, RECORDER_DATA & 0xFF, RECORDER_DATA >> 8, 0x00)
        + b"".join(sdo(0x60 | (0x10 * (n % 2))) for n in range(14)),
        "recorder_settings_refused_while_armed": bytes([NO_REFUSAL])
        + download(RECORDER_CHANNELS, 1, 0x2100, 2)
        + download(RECORDER_CHANNELS, 0, 1, 1)
        + download(RECORDER_STATE, 0, ARMED, 1)
        + download(RECORDER_CHANNELS, 1, 0x2101, 2)
        + sdo(0x40, RECORDER_DATA & 0xFF, RECORDER_DATA >> 8, 0x00)
        + download(RECORDER_STATE, 0, IDLE, 1),
        # Heartbeat consumer: watch the master (10 ms), hear it, lose it (1.6 s of silence), hear it
        # again; a second entry for the same node is refused; stored and reset.
        "heartbeat_consumer_timeout": bytes([NO_REFUSAL])
        + download(CONSUMER_HEARTBEAT, 1, (MASTER_ID << 16) | 10, 4)
        + master_heartbeat()
        + master_heartbeat(dt=100)
        + master_heartbeat(dt=0xFF)
        + download(CONSUMER_HEARTBEAT, 1, (MASTER_ID << 16) | 20, 4)
        + sdo(0x23, 0x10, 0x10, 0x02, *b"save")
        + frame(NMT, bytes([0x82, NODE_ID])),
        # The same on control time: SYNCs are the clock.
        "heartbeat_consumer_control_clock": bytes([NO_REFUSAL | CONTROL_CLOCK])
        + nmt_start()
        + download(CONSUMER_HEARTBEAT, 1, (MASTER_ID << 16) | 2, 4)
        + master_heartbeat()
        + frame(SYNC, dt=125)
        + frame(SYNC, dt=125)
        + master_heartbeat()
        + b"".join(frame(SYNC, dt=125) for _ in range(3)),
        # LSS: into configuration, inquire, a new id (taken at reset communication), then none
        # at all (LSS only), fastscan of the node without an id, and an id again.
        "lss_new_id_then_none_then_fastscan": bytes([NO_REFUSAL])
        + lss(command_frame(LssCommand.SWITCH_STATE_GLOBAL, LssState.CONFIGURATION))
        + lss(command_frame(LssCommand.INQUIRE_NODE_ID))
        + lss(command_frame(LssCommand.INQUIRE_SERIAL))
        + lss(command_frame(LssCommand.CONFIGURE_NODE_ID, 0x11))
        + lss(command_frame(LssCommand.STORE_CONFIGURATION))
        + lss(command_frame(LssCommand.SWITCH_STATE_GLOBAL, LssState.WAITING))
        + frame(NMT, bytes([0x82, NODE_ID]))
        + sdo(0x40, 0x18, 0x10, 0x04)
        + lss(command_frame(LssCommand.SWITCH_STATE_GLOBAL, LssState.CONFIGURATION))
        + lss(command_frame(LssCommand.CONFIGURE_NODE_ID, NODE_ID_UNCONFIGURED))
        + frame(NMT, bytes([0x82, 0]))
        + lss(command_frame(LssCommand.SWITCH_STATE_GLOBAL, LssState.WAITING))
        + lss(command_frame(LssCommand.IDENTIFY_NON_CONFIGURED_REMOTE))
        + lss(fastscan_frame(0, FASTSCAN_CONFIRM, 0, 0))
        + lss(fastscan_frame(0, 31, 0, 0))
        + lss(fastscan_frame(0, 0, 0, 1))
        + lss(command_frame(LssCommand.SWITCH_STATE_GLOBAL, LssState.CONFIGURATION))
        + lss(command_frame(LssCommand.CONFIGURE_NODE_ID, 0x12))
        + lss(command_frame(LssCommand.SWITCH_STATE_GLOBAL, LssState.WAITING))
        + sdo(0x40, 0x18, 0x10, 0x04),
        "program_download": bytes([NO_REFUSAL]) + program_download(product_code, bytes(range(200))),
        "program_download_wrong_board": bytes([NO_REFUSAL])
        + program_download(product_code ^ 1, bytes(range(200))),
        "store_then_reset_node": bytes([NO_REFUSAL | 0x40])
        + sdo(0x23, 0x00, 0x25, 0x00, *struct.pack("<f", 0.5))
        + sdo(0x23, 0x10, 0x10, 0x01, *b"save")
        + frame(NMT, bytes([0x81, NODE_ID])),
    }


def main() -> None:
    out = Path(__file__).resolve().parent / "corpus" / "frames"
    out.mkdir(parents=True, exist_ok=True)
    for name, data in seeds().items():
        (out / name).write_bytes(data)
    print(f"wrote {len(seeds())} seeds to {out}")


if __name__ == "__main__":
    main()
