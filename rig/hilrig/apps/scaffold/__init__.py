"""`hilrig new-board NAME`: a new board's project folder, from the template beside this file.

The template (`template/`) is a whole project that builds against the installed firmware package
(`find_package(hilfw)`) and passes its scenario as generated: a minimal table (the standard blocks
come from the table's defaults), the firmware's `main` and its components, the CMake build, a
plant, the pytest configuration, one scenario, a CI example. Names in it are spelt with the
placeholders of `Placeholders`; file names too (`{{board}}_plant.py`).

The folder is written whole or not at all: into a temporary folder beside the target, renamed
into place at the end (an error or Ctrl-C leaves nothing behind).
"""

from __future__ import annotations

import os
import re
import shutil
import tempfile
import zlib
from dataclasses import dataclass
from importlib import resources
from importlib.resources.abc import Traversable
from pathlib import Path

from hilrig.errors import RigError

TEMPLATE = "template"
"""The template's folder in this package."""

DOT_PREFIX = "dot-"
"""A template file or folder whose name starts with a dot is stored with this prefix instead."""

NAME_PATTERN = re.compile(r"[a-z][a-z0-9_]{0,30}")
"""A board's name: a C++ and Python identifier, lower case (it names the firmware, the plant
module and the test file)."""

VENDOR_ID = 0x48494C00
"""The template's 0x1018 vendor id ("HIL\\0", not a CiA-registered vendor): a team puts its own."""


class ScaffoldError(RigError):
    """The board cannot be scaffolded (a bad name, a folder in the way)."""


@dataclass(frozen=True)
class Placeholders:
    """What `{{key}}` stands for in the template's files and file names."""

    board: str
    """The board's name, e.g. `fan`."""
    product_code: int
    node_id: int

    @property
    def values(self) -> dict[str, str]:
        return {
            "board": self.board,
            "Board": "".join(part.capitalize() for part in self.board.split("_")),
            "vendor_id": f"0x{VENDOR_ID:08X}",
            "product_code": f"0x{self.product_code:08X}",
            "node_id": f"0x{self.node_id:02X}",
        }

    def fill(self, text: str) -> str:
        for key, value in self.values.items():
            text = text.replace("{{" + key + "}}", value)
        return text


def product_code_of(board: str) -> int:
    """A product code (0x1018:2) the name gives: the CRC-32 of it, so boards scaffolded under
    different names differ, and the demo boards' identities are not taken by accident."""
    return zlib.crc32(board.encode()) or 1


def check_name(board: str) -> None:
    if not NAME_PATTERN.fullmatch(board):
        raise ScaffoldError(
            f"board name {board!r}: use lower-case letters, digits and _, starting with a letter "
            "(it names the firmware, the plant module and the scenario file), e.g. fan_controller"
        )


def _copy(source: Traversable, target: Path, placeholders: Placeholders) -> list[Path]:
    written: list[Path] = []
    for item in sorted(source.iterdir(), key=lambda entry: entry.name):
        if item.name == "__pycache__":
            continue
        name = placeholders.fill(item.name.removesuffix(".in"))
        if name.startswith(DOT_PREFIX):  # .github/, .gitignore: packaged without the dot
            name = "." + name.removeprefix(DOT_PREFIX)
        if item.is_dir():
            (target / name).mkdir()
            written += _copy(item, target / name, placeholders)
        else:
            (target / name).write_text(placeholders.fill(item.read_text(encoding="utf-8")), encoding="utf-8")
            written.append(target / name)
    return written


def new_board(board: str, folder: Path, *, node_id: int = 0x20) -> list[Path]:
    """Write the project of board `board` into `folder` (which must not exist or be empty);
    returns the files written, relative to `folder`."""
    check_name(board)
    if not 1 <= node_id <= 127:
        raise ScaffoldError(f"node id {node_id}: a CANopen node id is 1..127")
    if folder.exists() and (not folder.is_dir() or any(folder.iterdir())):
        raise ScaffoldError(f"{folder} exists and is not an empty folder: name a new one")
    placeholders = Placeholders(board=board, product_code=product_code_of(board), node_id=node_id)
    folder.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", dir=folder.parent))
    try:
        umask = os.umask(0)
        os.umask(umask)
        staging.chmod(0o777 & ~umask)  # a folder as mkdir makes it, not mkdtemp's private one
        written = _copy(resources.files(__package__) / TEMPLATE, staging, placeholders)
        if folder.exists():
            folder.rmdir()
        staging.rename(folder)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return [path.relative_to(staging) for path in written]


__all__ = ["NAME_PATTERN", "Placeholders", "ScaffoldError", "check_name", "new_board", "product_code_of"]
