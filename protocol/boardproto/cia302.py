"""The CiA 302-3 rules (program download) the firmware and `hilrig flash` share: the four
objects, the program control commands, the flash status layout, and the image header a
firmware image starts with.

One home, as `boardproto.cia301` is for CiA 301: the rig imports this module, and the firmware
includes `board/cia302.hpp`, which `boardproto.cia302_header` generates from it.

A download, as CiA 302-3 and CANopenNode's program download (Zephyr's canopen_program.c) do
it: write 0x1F51:01 = STOP, then CLEAR, block-download the image into 0x1F50:01, write START.
0x1F57:01 says how it went; 0x1F56:01 is the CRC-32 of the image that runs.

    header = ImageHeader(product_code=0x4A4E5431, software_version="0.1.0",
                         payload_length=len(payload), payload_crc32=zlib.crc32(payload))
    image = header.pack() + payload
    ImageHeader.unpack(image[:IMAGE_HEADER_BYTES])   # ImageError when it is not one
"""

from __future__ import annotations

import enum
import struct
import zlib
from dataclasses import dataclass

PROGRAM_DATA_INDEX = 0x1F50
"""DOMAIN, write-only: the image, by block download (sub PROGRAM_NUMBER)."""
PROGRAM_CONTROL_INDEX = 0x1F51
"""UNSIGNED8: write a ProgramControl, read the program's state (the last command that took)."""
SOFTWARE_ID_INDEX = 0x1F56
"""UNSIGNED32, read-only: CRC-32 (zlib's) of the image the node runs."""
FLASH_STATUS_INDEX = 0x1F57
"""UNSIGNED32, read-only: the flash status (flash_status())."""
PROGRAM_NUMBER = 1
"""The one program a node has: the sub-index of every object above (sub 0 reads 1)."""


class ProgramControl(enum.IntEnum):
    """0x1F51 values (CiA 302-3). RESET (2) is not supported: the node refuses it."""

    STOP = 0
    START = 1
    CLEAR = 3


class FlashError(enum.IntEnum):
    """0x1F57 bits 1..7: what went wrong with the last download (0: nothing). 1..7 are CiA
    302-3's; 64..127 are manufacturer-specific ones of this project."""

    NO_ERROR = 0
    NO_VALID_PROGRAM = 1
    DATA_FORMAT_UNKNOWN = 2
    DATA_FORMAT_ERROR = 3
    FLASH_NOT_CLEARED = 4
    FLASH_WRITE_ERROR = 5
    GENERAL_ADDRESS_ERROR = 6
    FLASH_SECURED = 7
    WRONG_BOARD = 64
    """The image's product code is not this board's (0x1018:02)."""
    TRANSFER_BROKEN_OFF = 65
    """The download was aborted or timed out: the staged image was discarded."""


FLASH_IN_PROGRESS_BIT = 0x01
"""0x1F57 bit 0: a download is under way."""
FLASH_ERROR_SHIFT = 1


def flash_status(error: FlashError, in_progress: bool = False) -> int:
    """The 0x1F57 value of `error` (bits 1..7) and the in-progress bit."""
    return (int(error) << FLASH_ERROR_SHIFT) | (FLASH_IN_PROGRESS_BIT if in_progress else 0)


def flash_error(status: int) -> FlashError | int:
    """The error of a 0x1F57 value: a FlashError, or the bare number of one this module lacks."""
    value = (status >> FLASH_ERROR_SHIFT) & 0x7F
    try:
        return FlashError(value)
    except ValueError:
        return value


# --- Image header ------------------------------------------------------------------------------

IMAGE_MAGIC = b"HILFWIMG"
IMAGE_FORMAT_VERSION = 1
IMAGE_VERSION_BYTES = 32
"""The 0x100A string's room in the header, NUL-padded (the firmware's stamped slot is as long)."""
SOFTWARE_VERSION_SECTION = ".hil_software_version"
"""The ELF section of a Linux-target firmware that holds its 0x100A string (IMAGE_VERSION_BYTES,
NUL-padded): `boardproto image --version` stamps another version into a copy there."""


class ImageField(enum.IntEnum):
    """Byte offsets of the header's fields, little-endian; the struct below is the same layout."""

    MAGIC = 0  # IMAGE_MAGIC, 8 bytes
    FORMAT_VERSION = 8  # u16
    HEADER_BYTES = 10  # u16: IMAGE_HEADER_BYTES
    PRODUCT_CODE = 12  # u32: 0x1018:02 of the board it is for
    PAYLOAD_LENGTH = 16  # u32: bytes after the header
    PAYLOAD_CRC32 = 20  # u32: zlib CRC-32 of the payload (0x1F56 once it runs)
    SOFTWARE_VERSION = 24  # IMAGE_VERSION_BYTES: 0x100A of the payload, NUL-padded
    HEADER_CRC32 = 56  # u32: zlib CRC-32 of bytes 0..55


_HEADER = struct.Struct(f"<8sHHIII{IMAGE_VERSION_BYTES}sI")
IMAGE_HEADER_BYTES = _HEADER.size
assert IMAGE_HEADER_BYTES == ImageField.HEADER_CRC32 + 4


class ImageError(ValueError):
    """Not an image for this board; `error` is the 0x1F57 error the firmware reports for it."""

    def __init__(self, message: str, error: FlashError) -> None:
        super().__init__(message)
        self.error = error


@dataclass(frozen=True)
class ImageHeader:
    """The 60 bytes in front of a firmware image."""

    product_code: int
    software_version: str
    payload_length: int
    payload_crc32: int

    def pack(self) -> bytes:
        version = self.software_version.encode("ascii")
        if not version or len(version) > IMAGE_VERSION_BYTES or b"\0" in version:
            raise ValueError(
                f"software version {self.software_version!r}: 1..{IMAGE_VERSION_BYTES} ASCII characters"
            )
        body = _HEADER.pack(
            IMAGE_MAGIC,
            IMAGE_FORMAT_VERSION,
            IMAGE_HEADER_BYTES,
            self.product_code,
            self.payload_length,
            self.payload_crc32,
            version,
            0,
        )[: ImageField.HEADER_CRC32]
        return body + struct.pack("<I", zlib.crc32(body))

    @classmethod
    def unpack(cls, data: bytes) -> ImageHeader:
        """The header at the start of `data`; ImageError when it is none (the firmware's checks,
        in its order)."""
        if len(data) < IMAGE_HEADER_BYTES:
            raise ImageError(
                f"{len(data)} bytes: shorter than an image header", FlashError.DATA_FORMAT_UNKNOWN
            )
        magic, fmt, size, product, length, crc, version, header_crc = _HEADER.unpack_from(data)
        if magic != IMAGE_MAGIC:
            raise ImageError("not a firmware image (no HILFWIMG header)", FlashError.DATA_FORMAT_UNKNOWN)
        if fmt != IMAGE_FORMAT_VERSION or size != IMAGE_HEADER_BYTES:
            raise ImageError(
                f"image header format {fmt} is not {IMAGE_FORMAT_VERSION}", FlashError.DATA_FORMAT_UNKNOWN
            )
        if zlib.crc32(data[: ImageField.HEADER_CRC32]) != header_crc:
            raise ImageError("image header CRC does not match", FlashError.DATA_FORMAT_ERROR)
        text = version.rstrip(b"\0")
        if not text or b"\0" in text:
            raise ImageError("image header has no software version", FlashError.DATA_FORMAT_ERROR)
        return cls(product, text.decode("ascii", errors="replace"), length, crc)

    def check_board(self, product_code: int) -> None:
        """ImageError (WRONG_BOARD) unless the image is for a board with `product_code`."""
        if self.product_code != product_code:
            raise ImageError(
                f"image is for product code 0x{self.product_code:08X}, this board is 0x{product_code:08X}",
                FlashError.WRONG_BOARD,
            )

    def check_payload(self, payload: bytes) -> None:
        """ImageError (DATA_FORMAT_ERROR) unless `payload` is the one the header describes."""
        if len(payload) != self.payload_length:
            raise ImageError(
                f"payload is {len(payload)} bytes, the header says {self.payload_length}",
                FlashError.DATA_FORMAT_ERROR,
            )
        if zlib.crc32(payload) != self.payload_crc32:
            raise ImageError("payload CRC-32 does not match the header", FlashError.DATA_FORMAT_ERROR)
