"""Write the hand-made seeds of fuzz_canopen_frames into corpus/frames/ (committed).

Run from anywhere: python3 firmware/canopen/fuzz/make_seeds.py
The byte layout is documented at the top of FrameFuzzer.cpp.
"""

from __future__ import annotations

import struct
from pathlib import Path

NODE_ID = 0x10
NO_REFUSAL = 63  # config byte: refuse no field, storage empty

# Identifier classes of FrameFuzzer.cpp.
NMT, SYNC, SDO, RPDO1, RPDO2, RPDO3 = 0, 1, 2, 4, 5, 6


def frame(cls: int, data: bytes = b"", dt: int = 0) -> bytes:
    """One record: class, length, time step before it, data."""
    assert len(data) <= 8
    return bytes([(cls << 4) | len(data), dt]) + data


def sdo(*data: int, dt: int = 0) -> bytes:
    return frame(SDO, bytes(data).ljust(8, b"\0"), dt)


def nmt_start() -> bytes:
    return frame(NMT, bytes([0x01, NODE_ID]))


def seeds() -> dict[str, bytes]:
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
        + sdo(0x23, 0x05, 0x10, 0x00, (0x600 + NODE_ID) & 0xFF, (0x600 + NODE_ID) >> 8)
        + sdo(0x40, 0x00, 0x10, 0x00),
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
