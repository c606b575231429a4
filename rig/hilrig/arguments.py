"""The kinds argument types carry: `ArgKind` tags an argument type (`kind`) with the kind of value
it takes, so the bad-input table test (rig/tests/test_cli_bad_input.py) can feed every argument of
every command the bad inputs of its kind. Here, below every layer, because the run description's
options (`hilrig.session.run`) carry them as the command line's own (`hilrig.cli.files`) do: and
so the argument types those options take (numbers, a node id, an input file) are here too.
"""

from __future__ import annotations

import argparse
import os
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from boardproto.cia301 import MAX_NODE_ID, MIN_NODE_ID, is_node_id
from hilrig.errors import one_line


@dataclass(frozen=True)
class ArgKind:
    """What kind of value an argument type takes, set on the type function as `.kind`: the
    bad-input table test (rig/tests/test_cli_bad_input.py) feeds every argument of every command
    the bad values of its kind. `suffixes`: the extensions an input or output file takes;
    `sniffed`: an input file's content is checked before the command runs (else a wrong
    extension is its wrong format); `out_of_range`: a value of the right spelling refused."""

    name: str  # "input file", "output file", "number", "port", "name", "viewer"
    suffixes: tuple[str, ...] = ()
    sniffed: bool = False
    out_of_range: str = ""


def kind(value: ArgKind) -> Callable[[Callable[[str], Any]], Callable[[str], Any]]:
    """Decorator: tag an argument type with its ArgKind."""

    def tag(function: Callable[[str], Any]) -> Callable[[str], Any]:
        function.kind = value  # type: ignore[attr-defined]
        return function

    return tag


@kind(ArgKind("number", out_of_range="-1"))
def positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of seconds > 0, got {text!r}") from None
    if not value > 0.0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text}")
    return value


@kind(ArgKind("number", out_of_range="0"))
def positive_int(text: str) -> int:
    try:
        value = int(text, 0)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number > 0, got {text!r}") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"expected a whole number > 0, got {text}")
    return value


@kind(ArgKind("number", out_of_range=str(MAX_NODE_ID + 1)))
def node_id(text: str) -> int:
    """'16' or '0x10' -> 16; 1..127."""
    try:
        value = int(text, 0)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected a node id {MIN_NODE_ID}..{MAX_NODE_ID} (decimal or 0x hex, e.g. 0x10), got {text!r}"
        ) from None
    if not is_node_id(value):
        raise argparse.ArgumentTypeError(
            f"expected a node id {MIN_NODE_ID}..{MAX_NODE_ID} (decimal or 0x hex, e.g. 0x10), got {text}"
        )
    return value


# --- Input files -----------------------------------------------------------------------------
def unreadable_reason(path: Path) -> str | None:
    """Why the file at `path` cannot be read ('does not exist', 'is a directory', 'cannot be read:
    Permission denied'), None if it can. Tried by opening it, so root and ACLs judge as they will
    when the command reads it."""
    try:
        with path.open("rb"):
            return None
    except FileNotFoundError:
        return "does not exist"
    except IsADirectoryError:
        return "is a directory, not a file"
    except OSError as error:
        return f"cannot be read: {error.strerror or one_line(error)}"


def existing_file(
    what: str,
    hint: str,
    *,
    suffixes: tuple[str, ...] = (),
    sniff: Callable[[Path], str | None] | None = None,
) -> Callable[[str], Path]:
    """An argument type: a file that exists and can be read (else a usage error naming it, with
    `hint`); with `suffixes`, one of these extensions; with `sniff`, whose content `sniff`
    accepts (it returns why not, or None)."""

    @kind(ArgKind("input file", suffixes, sniffed=sniff is not None))
    def check(text: str) -> Path:
        path = Path(text)
        reason = unreadable_reason(path)
        if reason is None and suffixes and not text.lower().endswith(suffixes):
            reason = f"does not end in {suffix_choice(suffixes)}"
        if reason is None and sniff is not None:
            reason = sniff(path)
        if reason is not None:
            raise argparse.ArgumentTypeError(f"{what} {text} {reason}; {hint}")
        return path

    return check


def suffix_choice(suffixes: tuple[str, ...]) -> str:
    """'.log, .blf or .asc'."""
    return " or ".join(filter(None, (", ".join(suffixes[:-1]), suffixes[-1])))


_EDS_OBJECT = re.compile(rb"^\s*\[[0-9A-Fa-f]{4}\]", re.MULTILINE)


def sniff_eds(path: Path) -> str | None:
    """An EDS (CiA 306) is INI text with a section per object ([1000], [1018]...)."""
    return None if _EDS_OBJECT.search(path.read_bytes()) else "is not an EDS (no [1000]-style object section)"


def sniff_executable(path: Path) -> str | None:
    if not os.access(path, os.X_OK):
        return "is not executable (chmod +x)"
    with path.open("rb") as file:
        start = file.read(4)
    return (
        None if start in (b"\x7fELF",) or start.startswith(b"#!") else "is not a program (no ELF or #! start)"
    )


__all__ = [
    "ArgKind",
    "existing_file",
    "kind",
    "node_id",
    "positive_float",
    "positive_int",
    "sniff_eds",
    "sniff_executable",
    "suffix_choice",
    "unreadable_reason",
]
