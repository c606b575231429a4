"""The kinds argument types carry: `ArgKind` tags an argument type (`kind`) with the kind of value
it takes, so the bad-input table test (rig/tests/test_cli_bad_input.py) can feed every argument of
every command the bad inputs of its kind. Here, below every layer, because the run description's
options (`hilrig.session.run`) carry them as the command line's own (`hilrig.cli.files`) do.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any


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


__all__ = ["ArgKind", "kind", "positive_float", "positive_int"]
