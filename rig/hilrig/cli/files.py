"""Argument types of files, and the kinds argument types carry.

`ArgKind` tags each argument type with the kind of value it takes (`kind`); the bad-input table
test (rig/tests/test_cli_bad_input.py) feeds every argument of every command the bad inputs of its
kind. An input file is checked before the command runs: it exists, is no folder, can be read, has
its extension and, where a cheap look at it tells, its format (`sniff_*`); an output file's
folder must exist (none is made: a typo would make one anywhere, as root too).
"""

from __future__ import annotations

import argparse
import os
import re
from collections.abc import Callable
from pathlib import Path

from hilrig.arguments import ArgKind, kind, suffix_choice
from hilrig.arguments import existing_file as existing_file  # the commands import them from here
from hilrig.arguments import sniff_eds as sniff_eds
from hilrig.arguments import sniff_executable as sniff_executable
from hilrig.arguments import unreadable_reason as unreadable_reason
from hilrig.errors import one_line


def output_file(what: str, *, suffixes: tuple[str, ...] = ()) -> Callable[[str], Path]:
    """An argument type: a file to write, in a folder that exists (none is created: a typo
    would make one anywhere, as root too) and that is no folder itself."""

    @kind(ArgKind("output file", suffixes))
    def check(text: str) -> Path:
        path = Path(text)
        folder = path.parent
        if suffixes and not text.lower().endswith(suffixes):
            reason = f"does not end in {suffix_choice(suffixes)} (the format follows the extension)"
        elif path.is_dir() or text.endswith("/"):
            reason = "is a directory: name the file to write"
        elif not folder.is_dir():
            reason = f"cannot be written: folder {folder} does not exist (create it first)"
        elif not os.access(folder, os.W_OK | os.X_OK, effective_ids=os.access in os.supports_effective_ids):
            reason = f"cannot be written: folder {folder} is not writable"
        else:
            return path
        raise argparse.ArgumentTypeError(f"{what} {text} {reason}")

    return check


@kind(ArgKind("output folder"))
def output_folder(text: str) -> Path:
    """An argument type: a folder the command writes into (made if missing, as `make run`'s
    out/demo is); an existing file there is refused."""
    path = Path(text)
    if path.exists() and not path.is_dir():
        raise argparse.ArgumentTypeError(f"{text} is a file, not a folder: name a folder to write into")
    return path


# --- What a file's start says about its format (the sniff of `existing_file`) ------------
def sniff_toml(path: Path) -> str | None:
    import tomllib

    try:
        tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as error:
        return f"is not TOML ({one_line(error)})"
    return None


_DBC_KEYWORD = re.compile(rb"^\s*(VERSION|NS_|BU_|BO_)\b", re.MULTILINE)


def sniff_dbc(path: Path) -> str | None:
    """A DBC has its keywords (VERSION, BU_, BO_...) at line starts."""
    return None if _DBC_KEYWORD.search(path.read_bytes()) else "is not a DBC (no VERSION, BU_ or BO_ line)"
