"""The generated `board/cia302.hpp`: every program download rule of `boardproto.cia302` is in it
with the same value (object indices, program control values, flash errors and the status layout,
the image header's magic, size and field offsets), it says it is generated, and it compiles with
the project's flags. And the image header's own rules: a round trip, and each refusal's error."""

from __future__ import annotations

import shutil
import zlib
from pathlib import Path

import pytest
from header_check import compile_header_check

from boardproto import cia302
from boardproto.cia301_header import cpp_name
from boardproto.cia302_header import GENERATED_BANNER, generate_cia302_header


def test_the_generate_command_writes_it_with_the_banner(generated_dir: Path) -> None:
    header = (generated_dir / "include" / "board" / "cia302.hpp").read_text()
    assert header.startswith(GENERATED_BANNER + "\n")
    assert header == generate_cia302_header()


def _value_asserts() -> str:
    checks = [
        ("kProgramDataIndex", cia302.PROGRAM_DATA_INDEX),
        ("kProgramControlIndex", cia302.PROGRAM_CONTROL_INDEX),
        ("kSoftwareIdIndex", cia302.SOFTWARE_ID_INDEX),
        ("kFlashStatusIndex", cia302.FLASH_STATUS_INDEX),
        ("kProgramNumber", cia302.PROGRAM_NUMBER),
        ("kFlashInProgressBit", cia302.FLASH_IN_PROGRESS_BIT),
        ("kFlashErrorShift", cia302.FLASH_ERROR_SHIFT),
        ("kImageFormatVersion", cia302.IMAGE_FORMAT_VERSION),
        ("kImageHeaderBytes", cia302.IMAGE_HEADER_BYTES),
        ("kImageVersionBytes", cia302.IMAGE_VERSION_BYTES),
    ]
    lines = [f"static_assert({name} == {value});" for name, value in checks]
    for python_enum in (cia302.ProgramControl, cia302.FlashError):
        lines += [
            f"static_assert(static_cast<int>({python_enum.__name__}::{cpp_name(m)}) == {int(m)});"
            for m in python_enum
        ]
    lines += [f"static_assert(image_field::k{cpp_name(f)} == {int(f)});" for f in cia302.ImageField]
    lines += [f"static_assert(kImageMagic[{i}] == {byte});" for i, byte in enumerate(cia302.IMAGE_MAGIC)]
    status = cia302.flash_status(cia302.FlashError.WRONG_BOARD, True)
    lines.append(f"static_assert(flash_status(FlashError::WrongBoard, true) == {status});")
    return "\n".join(lines)


@pytest.mark.skipif(shutil.which("g++") is None, reason="needs g++")
def test_compiles_to_the_python_values(generated_dir: Path, tmp_path: Path) -> None:
    result = compile_header_check(generated_dir, tmp_path, "cia302.hpp", "cia302", _value_asserts())
    assert result.returncode == 0, result.stderr


def test_an_image_header_round_trips_and_each_refusal_names_its_flash_error() -> None:
    payload = bytes(range(256)) * 3
    header = cia302.ImageHeader(0x4A4E5431, "0.1.0-second", len(payload), zlib.crc32(payload))
    packed = header.pack()
    assert len(packed) == cia302.IMAGE_HEADER_BYTES
    assert cia302.ImageHeader.unpack(packed + payload) == header
    header.check_payload(payload)
    cases = [
        (b"NOTANIMG" + packed[8:], cia302.FlashError.DATA_FORMAT_UNKNOWN),
        (packed[:20] + bytes([packed[20] ^ 1]) + packed[21:], cia302.FlashError.DATA_FORMAT_ERROR),
        (packed[:30], cia302.FlashError.DATA_FORMAT_UNKNOWN),
    ]
    for data, error in cases:
        with pytest.raises(cia302.ImageError) as refused:
            cia302.ImageHeader.unpack(data)
        assert refused.value.error == error
    with pytest.raises(cia302.ImageError) as refused:
        header.check_board(0x4A4E5432)
    assert refused.value.error == cia302.FlashError.WRONG_BOARD
    with pytest.raises(cia302.ImageError) as refused:
        header.check_payload(payload[:-1])
    assert refused.value.error == cia302.FlashError.DATA_FORMAT_ERROR
    assert cia302.flash_error(cia302.flash_status(cia302.FlashError.TRANSFER_BROKEN_OFF)) == (
        cia302.FlashError.TRANSFER_BROKEN_OFF
    )
