"""Every argument of every command, fed the bad input of its kind, ends in one line on stderr and
exit code 2 (`hilrig --help`'s rule: refused before anything ran), never a traceback.

The commands and their arguments come from the CLI's own parser, so a command added later is
covered without a line here: an argument's kind is the `ArgKind` its type carries
(`hilrig.cli.files.kind`): missing file, directory, unreadable file, wrong format, out-of-range
number, unknown name, port out of range, no display. An argument taking a path unchecked
(`type=Path`) fails the test: give it `existing_file`, `output_file` or `output_folder`. Natively,
no bus: every case is refused before a bus is opened.
"""

from __future__ import annotations

import argparse
import os
import socket
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from hilrig.cli import EXIT_USAGE, build_parser, main
from hilrig.cli.files import ArgKind

Make = Callable[[Path], str]
"""Writes what a case needs under the test's folder; returns the bad argument's text."""


@dataclass(frozen=True)
class Case:
    command: tuple[str, ...]
    argument: str  # its option string, or the positional's metavar
    option: str | None  # None: a positional
    label: str  # the kind of bad input
    make: Make
    expected: str = ""  # a text the error line holds ("" : the bad argument's text)
    no_display: bool = False


def leaf_parsers(
    parser: argparse.ArgumentParser, path: tuple[str, ...] = ()
) -> Iterator[tuple[tuple[str, ...], argparse.ArgumentParser]]:
    """(command words, parser) of every runnable command, sub-commands (`sdo read`) included."""
    subparsers = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subparsers:
        yield path, parser
        return
    for name, child in subparsers[0].choices.items():
        yield from leaf_parsers(child, (*path, name))


def arguments(parser: argparse.ArgumentParser) -> Iterator[argparse.Action]:
    for action in parser._actions:
        if not isinstance(action, argparse._HelpAction | argparse._SubParsersAction) and action.nargs != 0:
            yield action


def _file(name: str, content: bytes = b"x\n") -> Make:
    def make(tmp_path: Path) -> str:
        path = tmp_path / name
        path.write_bytes(content)
        return str(path)

    return make


def _folder(name: str) -> Make:
    def make(tmp_path: Path) -> str:
        (tmp_path / name).mkdir()
        return str(tmp_path / name)

    return make


def _unreadable(name: str) -> Make:
    """A file that exists and cannot be read: mode 000, or for root (who reads any mode) a Unix
    socket, which no one can open."""

    def make(tmp_path: Path) -> str:
        path = tmp_path / name
        if os.geteuid() != 0:
            path.write_bytes(b"x\n")
            path.chmod(0)
            return str(path)
        cwd = Path.cwd()
        os.chdir(tmp_path)  # a socket's path is limited to 107 bytes: bind the short name
        try:
            listener = socket.socket(socket.AF_UNIX)
            listener.bind(name)
            listener.close()
        finally:
            os.chdir(cwd)
        return str(path)

    return make


def _text(text: str) -> Make:
    return lambda _: text


GARBAGE = b"\x00\xff this is no file of that kind\n"


def bad_inputs(action: argparse.Action) -> list[tuple[str, Make, str, bool]]:
    """(label, make, expected text, no display) for each bad input of the action's kind."""
    kind: ArgKind | None = getattr(action.type, "kind", None)
    if action.choices is not None and kind is None:
        return [("unknown name", _text("no_such_choice"), "no_such_choice", False)]
    if kind is None:
        if action.type in (int, float):
            return [("not a number", _text("not-a-number"), "not-a-number", False)]
        return []
    suffix = kind.suffixes[0] if kind.suffixes else ""
    if kind.name == "input file":
        cases = [
            ("missing file", _text(f"/nonexistent/gone{suffix}"), "does not exist", False),
            ("directory", _folder(f"folder{suffix}"), "is a directory", False),
            ("unreadable file", _unreadable(f"locked{suffix}"), "cannot be read", False),
        ]
        if kind.sniffed or kind.suffixes:  # a file of no known format has no wrong one
            wrong = ("bad" + suffix, GARBAGE) if kind.sniffed else ("bad.xyz", b"x\n")
            cases.append(("wrong format", _file(*wrong), wrong[0], False))
        return cases
    if kind.name == "output file":
        cases = [
            ("missing folder", _text(f"/nonexistent/out{suffix}"), "/nonexistent does not exist", False),
            ("directory", _folder(f"folder{suffix}"), "is a directory", False),
        ]
        if suffix:
            cases.append(("wrong format", _text("out.xyz"), "out.xyz", False))
        return cases
    if kind.name == "output folder":
        return [("a file, not a folder", _file("file.txt"), "is a file, not a folder", False)]
    if kind.name == "viewer":
        return [
            ("port out of range", _text(kind.out_of_range), "out of range", False),
            ("no display", _text("spawn"), "no display", True),
        ]
    label = {"number": "out-of-range number", "port": "port out of range", "name": "unknown name"}
    named = kind.out_of_range.partition("=")[0]  # NAME=VALUE: the error names NAME
    return [(label[kind.name], _text(kind.out_of_range), named, False)]


def all_cases() -> list[Case]:
    cases = []
    for command, parser in leaf_parsers(build_parser()):
        positionals = [a for a in arguments(parser) if not a.option_strings]
        for action in arguments(parser):
            name = action.option_strings[-1] if action.option_strings else str(action.metavar or action.dest)
            for label, make, expected, no_display in bad_inputs(action):
                if not action.option_strings and positionals.index(action) > 0:
                    continue  # only a command's first positional is fed alone (none other is typed yet)
                option = action.option_strings[-1] if action.option_strings else None
                cases.append(Case(command, name, option, label, make, expected, no_display))
        required = [a for a in positionals if a.nargs in (None, 1)]
        if any(a.option_strings == ["--web"] for a in parser._actions) and len(required) <= 1:
            # Opens a native window unless --web: without a display it says to add --web.
            trace = _file("trace.rrd", b"RRF2 a recording")
            cases.append(Case(command, "TRACE", None, "no display", trace, "add --web", True))
    return cases


CASES = all_cases()


def test_every_command_is_fed_bad_input() -> None:
    """Each command has at least one argument whose bad input is tried (a command with none
    would pass this file without a case)."""
    commands = {command for command, _ in leaf_parsers(build_parser())}
    assert commands == {case.command for case in CASES}, commands - {case.command for case in CASES}
    kinds = {case.label for case in CASES}
    assert {
        "missing file",
        "directory",
        "unreadable file",
        "wrong format",
        "out-of-range number",
        "unknown name",
        "port out of range",
        "no display",
    } <= kinds


def test_no_argument_takes_a_path_unchecked() -> None:
    unchecked = [
        f"hilrig {' '.join(command)} {action.option_strings or action.dest}"
        for command, parser in leaf_parsers(build_parser())
        for action in arguments(parser)
        if action.type is Path
    ]
    assert unchecked == [], "give these existing_file, output_file or output_folder"


@pytest.mark.parametrize("case", CASES, ids=[f"{' '.join(c.command)} {c.argument}: {c.label}" for c in CASES])
def test_bad_input_is_one_line_and_exit_code_2(
    case: Case, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)
    for name in ("DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET"):
        monkeypatch.delenv(name, raising=False)
    if not case.no_display:
        monkeypatch.setenv("DISPLAY", ":0")  # only the no-display case lacks one
    bad = case.make(tmp_path)
    argv = [*case.command, *((case.option,) if case.option else ()), bad]
    code = main(argv)
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    assert err.count("\n") == 1 and err.startswith(f"hilrig {case.command[0]}"), err
    assert (case.expected or bad) in err, err
    assert code == EXIT_USAGE, err
    assert out == ""
