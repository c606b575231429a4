"""CiA 302-3 program download to one board (`boardproto.cia302`): stop the program, clear the
staged one, send the image into 0x1F50 by SDO block transfer (with CRC), start it, wait for the
boot-up of the new image, then read back its 0x100A version and 0x1F56 software id.

    image = Path("build/release/images/joint-firmware-second.img").read_bytes()
    result = flash(node, image, progress=lambda sent, total: ...)
    result.software_version, result.software_id       # '0.1.0-second', 0x5A1C...

An exception mid-transfer (the board refused the header, the bus went away, KeyboardInterrupt)
sends the SDO abort: the board discards what it staged and runs on with its old image.
"""

from __future__ import annotations

import contextlib
import io
from collections.abc import Callable
from dataclasses import dataclass

from canopen.sdo import SdoAbortedError, SdoClient
from canopen.sdo.client import BlockDownloadStream

from boardproto.cia301 import SdoAbortCode
from boardproto.cia302 import (
    FLASH_STATUS_INDEX,
    PROGRAM_CONTROL_INDEX,
    PROGRAM_DATA_INDEX,
    PROGRAM_NUMBER,
    SOFTWARE_ID_INDEX,
    ProgramControl,
)
from hilrig.wire.node import BoardNode, SocketSdoClient

SOFTWARE_VERSION_INDEX = 0x100A
"""CiA 301 manufacturer software version (VISIBLE_STRING)."""
SEGMENT_BYTES = 7
PROGRESS_STEPS = 10
"""Progress is reported this many times over a transfer: every 10 %, the last at its end."""

ProgressCallback = Callable[[int, int], None]
"""Called with (bytes sent, bytes in all)."""


@dataclass(frozen=True)
class FlashResult:
    """What the board answers after it restarted from the new image."""

    software_version: str  # 0x100A
    software_id: int  # 0x1F56:01, CRC-32 of the running image
    flash_status: int  # 0x1F57:01, 0 = no error


def control(node: BoardNode, command: ProgramControl) -> None:
    """Write 0x1F51:01 (an abort is SdoAbortError in words)."""
    node.download(
        PROGRAM_CONTROL_INDEX,
        PROGRAM_NUMBER,
        bytes([int(command)]),
        f"program control {command.name.lower()}",
    )


def start(node: BoardNode) -> None:
    """0x1F51:01 = START: with a complete image downloaded, the board restarts from it (its
    boot-up follows); without one, the stopped program runs again."""
    control(node, ProgramControl.START)


def read_u32(node: BoardNode, index: int) -> int:
    return int.from_bytes(node.upload(index, PROGRAM_NUMBER), "little")


def software_version(node: BoardNode) -> str:
    return node.upload(SOFTWARE_VERSION_INDEX, 0, "read 0x100A").decode("ascii", errors="replace")


def download(node: BoardNode, image: bytes, progress: ProgressCallback | None = None) -> None:
    """Stop, clear, and block-download `image` into 0x1F50:01. Any exception on the way aborts
    the transfer (general error) before it propagates, so the board keeps its old image."""
    control(node, ProgramControl.STOP)
    control(node, ProgramControl.CLEAR)
    total = len(image)

    def transfer() -> None:
        sdo = node.remote.sdo
        batched = sdo.batched() if isinstance(sdo, SocketSdoClient) else contextlib.nullcontext()
        with batched:
            send(sdo)

    def send(sdo: SdoClient) -> None:
        stream = BlockDownloadStream(sdo, PROGRAM_DATA_INDEX, PROGRAM_NUMBER, size=total)
        try:
            view = memoryview(image)
            sent = 0
            reported = 0  # tenths (PROGRESS_STEPS) reported so far
            while sent < total:
                sent += stream.write(view[sent : sent + SEGMENT_BYTES]) or 0
                if progress is not None and sent * PROGRESS_STEPS // total > reported:
                    progress(sent, total)
                    reported = sent * PROGRESS_STEPS // total
            stream.close()  # the end request with the CRC; the board checks the image here
        except BaseException as error:
            # The board's own abort ended the transfer already; anything else ends it here.
            if not stream.closed and not isinstance(error, SdoAbortedError):
                sdo.abort(int(SdoAbortCode.GENERAL_ERROR))
            # Closed without canopen's end request, which would follow the abort otherwise.
            io.RawIOBase.close(stream)
            raise

    node.call_sdo("program download into 0x1F50", transfer)


def flash(
    node: BoardNode, image: bytes, *, progress: ProgressCallback | None = None, boot_timeout_s: float = 10.0
) -> FlashResult:
    """Download `image`, start it, and return what the restarted board reports."""
    download(node, image, progress)
    node.await_boot_up(lambda: start(node), boot_timeout_s)
    return FlashResult(
        software_version=software_version(node),
        software_id=read_u32(node, SOFTWARE_ID_INDEX),
        flash_status=read_u32(node, FLASH_STATUS_INDEX),
    )
