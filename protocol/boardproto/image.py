"""Wrap a built firmware executable into a CiA 302-3 download image (boardproto.cia302): the
image header (this board's product code, the 0x100A version, payload length and CRC-32), then
the executable.

    python -m boardproto image --table protocol/board.toml --firmware build/bin/joint-firmware \\
        --out build/images/joint-firmware.img [--version-suffix -second] [--strip]

The firmware answers 0x100A with the string in its `.hil_software_version` section
(firmware/platform/linux/SoftwareVersion.hpp). With --version-suffix the tool stamps another
string into a copy (objcopy --update-section, same size): the same build, a second image with
another version, which is what a flash test needs to tell the two apart. --strip drops the
symbols and debug information (objcopy --strip-all) so that the image is smaller on the bus.
The header's version is read back from the copy, so it is always the one the payload answers.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
import zlib
from pathlib import Path

from boardproto.cia302 import IMAGE_VERSION_BYTES, SOFTWARE_VERSION_SECTION, ImageHeader
from boardproto.table import BoardTable


class ImageBuildError(RuntimeError):
    """The executable could not be wrapped (no version section, objcopy failed...)."""


def _objcopy(*arguments: str) -> None:
    result = subprocess.run(["objcopy", *arguments], capture_output=True, text=True, check=False)
    if result.returncode != 0:
        raise ImageBuildError(f"objcopy {' '.join(arguments)}: {result.stderr.strip()}")


def read_version(executable: Path) -> str:
    """The 0x100A string stamped into `executable`."""
    with tempfile.TemporaryDirectory() as scratch:
        dump = Path(scratch) / "version"
        _objcopy(
            "--dump-section",
            f"{SOFTWARE_VERSION_SECTION}={dump}",
            str(executable),
            str(Path(scratch) / "copy"),
        )
        return dump.read_bytes()[:IMAGE_VERSION_BYTES].split(b"\0", 1)[0].decode("ascii")


def _stamp(executable: Path, version: str) -> None:
    with tempfile.TemporaryDirectory() as scratch:
        dump = Path(scratch) / "version"
        _objcopy(
            "--dump-section",
            f"{SOFTWARE_VERSION_SECTION}={dump}",
            str(executable),
            str(Path(scratch) / "copy"),
        )
        size = len(dump.read_bytes())
        encoded = version.encode("ascii")
        if len(encoded) >= min(size, IMAGE_VERSION_BYTES):
            raise ImageBuildError(f"version {version!r} does not fit the {IMAGE_VERSION_BYTES}-byte slot")
        dump.write_bytes(encoded.ljust(size, b"\0"))
        _objcopy("--update-section", f"{SOFTWARE_VERSION_SECTION}={dump}", str(executable))


def build_image(table: BoardTable, firmware: Path, *, version_suffix: str = "", strip: bool = False) -> bytes:
    """The image of `firmware` for the board of `table`."""
    with tempfile.TemporaryDirectory() as scratch:
        copy = Path(scratch) / firmware.name
        shutil.copyfile(firmware, copy)
        if strip:
            _objcopy("--strip-all", str(copy))
        if version_suffix:
            _stamp(copy, read_version(copy) + version_suffix)
        version = read_version(copy)
        payload = copy.read_bytes()
    header = ImageHeader(
        product_code=table.node.product_code,
        software_version=version,
        payload_length=len(payload),
        payload_crc32=zlib.crc32(payload),
    )
    return header.pack() + payload


def write_image(path: Path, image: bytes) -> None:
    """Write atomically (temporary file in the same directory, then rename)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    descriptor, temporary = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(descriptor, "wb") as file:
            file.write(image)
        os.chmod(temporary, 0o644)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
