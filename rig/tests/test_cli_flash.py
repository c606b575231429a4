"""`hilrig flash` checks the image before it opens a bus: a file that is no image, an image for
another product, a payload cut short or changed, each refused in one line with exit code 2
(nothing sent)."""

from __future__ import annotations

import zlib
from pathlib import Path

import pytest

from boardproto.cia302 import ImageHeader
from hilrig.cli import EXIT_USAGE, main
from hilrig.table import RigTable

TABLE = RigTable.load()
PAYLOAD = bytes(range(256)) * 40


def write_image(path: Path, *, product_code: int | None = None, payload: bytes = PAYLOAD) -> Path:
    header = ImageHeader(
        product_code=TABLE.board.node.product_code if product_code is None else product_code,
        software_version="1.2.3",
        payload_length=len(PAYLOAD),
        payload_crc32=zlib.crc32(PAYLOAD),
    )
    path.write_bytes(header.pack() + payload)
    return path


def refusal(capsys: pytest.CaptureFixture[str], image: Path) -> str:
    # A bus that does not exist: the refusal must come before any bus is opened.
    code = main(["flash", str(image), "-i", "socketcan", "-c", "no-such-can0"])
    err = capsys.readouterr().err
    assert code == EXIT_USAGE, err
    assert "Traceback" not in err and err.count("\n") == 1, err
    return err



def test_a_file_that_is_no_image(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "firmware.img"
    path.write_bytes(b"\x7fELF" + bytes(100))
    assert "is not a firmware image" in refusal(capsys, path)


def test_an_image_for_another_product(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_image(tmp_path / "other.img", product_code=0x12345678)
    assert "image is for product code 0x12345678" in refusal(capsys, path)


def test_an_image_cut_short(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_image(tmp_path / "cut.img", payload=PAYLOAD[:-100])
    assert "the header says" in refusal(capsys, path)


def test_an_image_whose_payload_changed(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    changed = bytearray(PAYLOAD)
    changed[5000] ^= 0x40
    path = write_image(tmp_path / "changed.img", payload=bytes(changed))
    assert "payload CRC-32 does not match" in refusal(capsys, path)
