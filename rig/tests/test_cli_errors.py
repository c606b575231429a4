"""Bad input is never a traceback: every file, definition or configuration a user can get wrong
ends the command with one line on stderr that names it, and the exit code of `hilrig --help`'s
rule: 2 refused before anything ran (fix the command line or what it names), 1 ran and failed
(a log's content breaks off). Also --version, `python -m hilrig`, -v after the command and the
bash completion script."""

from __future__ import annotations

import gzip
import importlib.util
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from boardproto.cia301 import SYNC_COB_ID
from hilrig import resources
from hilrig.cli import EXIT_FAILED, EXIT_USAGE, main, version
from hilrig.table import RigTable

CANDUMP_SCREEN = "  vcan0  080   [1]  01\n  vcan0  080   [1]  02\n"  # candump without -L
CANDUMP_LOG = f"(1700000000.000000) vcan0 {SYNC_COB_ID:03X}#01\n"  # candump -L
MF4_CODE = EXIT_USAGE if importlib.util.find_spec("asammdf") is None else EXIT_FAILED  # no reader / bad file
Setup = Callable[[Path, pytest.MonkeyPatch], list[str]]


def write(name: str, content: str | bytes) -> Callable[[Path], Path]:
    def make(tmp_path: Path) -> Path:
        path = tmp_path / name
        path.write_bytes(content if isinstance(content, bytes) else content.encode())
        return path

    return make


def replay(name: str, content: str | bytes, *options: str) -> Setup:
    return lambda tmp_path, _: ["replay", str(write(name, content)(tmp_path)), "--decode", *options]


def corrupt_dbc(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> list[str]:
    dbc = write("bad.dbc", 'VERSION ""\nBO_ garbage\n')(tmp_path)  # starts like one
    return [*replay("bus.log", CANDUMP_LOG)(tmp_path, monkeypatch), "--dbc", str(dbc)]


def missing_default_dbc(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> list[str]:
    monkeypatch.setattr(resources, "DEFAULT_DBC", tmp_path / "build" / "protocol" / "board.dbc")
    return ["replay", str(write("bus.log", CANDUMP_LOG)(tmp_path)), "--decode"]


def missing_default_eds(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> list[str]:
    monkeypatch.setattr(resources, "DEFAULT_EDS", tmp_path / "build" / "protocol" / "board.eds")
    return ["get", "velocity_kp", "-i", "virtual", "-c", f"errors-{tmp_path.name}"]


def with_file(option: str, name: str, content: str, *argv: str) -> Setup:
    return lambda tmp_path, _: [*argv, option, str(write(name, content)(tmp_path))]


def configured_interface(name: str) -> Setup:
    def setup(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> list[str]:
        monkeypatch.setenv("CAN_INTERFACE", name)
        return ["scan", "--listen", "0.1"]

    return setup


CASES: dict[str, tuple[Setup, int, list[str]]] = {
    "candump screen output as .log": (
        replay("screen.log", CANDUMP_SCREEN),
        EXIT_FAILED,
        ["screen.log: python-can cannot read this .log (candump -L) file", "candump's screen output"],
    ),
    "candump -L as .txt": (
        replay("bus.txt", CANDUMP_LOG),
        EXIT_USAGE,
        ["bus.txt: python-can reads no .txt files", ".blf", ".log (candump -L)", "name the file *.log"],
    ),
    ".mf4": (replay("bus.mf4", b"MDF     4.10"), MF4_CODE, ["bus.mf4: "]),
    "unknown extension": (
        replay("bus.xyz", "x"),
        EXIT_USAGE,
        ["bus.xyz: python-can reads no .xyz files", ".asc, .blf, .csv"],
    ),
    "no extension": (replay("bus", "x"), EXIT_USAGE, ["python-can reads no files without an extension"]),
    "missing log": (
        lambda tmp_path, _: ["replay", str(tmp_path / "gone.log")],
        EXIT_USAGE,
        ["gone.log does not exist; record one with `hilrig record FILE`", ".blf"],
    ),
    "corrupt .blf": (
        replay("bus.blf", b"\x00garbage" * 20),
        EXIT_FAILED,
        ["python-can cannot read this .blf"],
    ),
    "garbled part-way": (
        replay("cut.log", CANDUMP_LOG + "(zz) vcan0 12G#\n"),
        EXIT_FAILED,
        ["cut.log: python-can cannot read this .log (candump -L) file after frame 1"],
    ),
    "corrupt .log.gz": (
        replay("bus.log.gz", b"not gzip"),
        EXIT_FAILED,
        ["bus.log.gz: python-can cannot read"],
    ),
    "empty log": (replay("empty.log", ""), EXIT_USAGE, ["empty.log holds no frames"]),
    "missing default DBC": (
        missing_default_dbc,
        EXIT_USAGE,
        ["board.dbc does not exist; run `make build`, or give --dbc"],
    ),
    "corrupt DBC": (corrupt_dbc, EXIT_USAGE, ["bad.dbc is not a DBC cantools can read"]),
    "no DBC at all": (
        with_file("--dbc", "bad.dbc", "xyz", "replay", "--decode"),
        EXIT_USAGE,
        ["bad.dbc is not a DBC (no VERSION, BU_ or BO_ line)"],
    ),
    "missing default EDS": (
        missing_default_eds,
        EXIT_USAGE,
        ["board.eds does not exist; run `make build`, or give --eds"],
    ),
    "no EDS at all": (
        with_file("--eds", "bad.eds", "garbage\n", "get", "velocity_kp", "-i", "virtual", "-c", "errors-eds"),
        EXIT_USAGE,
        ["bad.eds is not an EDS (no [1000]-style object section)", "run `make build`, or give --eds"],
    ),
    "corrupt EDS": (
        with_file(
            "--eds",
            "bad.eds",
            "[1000]\nParameterName\n",
            "get",
            "velocity_kp",
            "-i",
            "virtual",
            "-c",
            "errors-eds",
        ),
        EXIT_USAGE,
        ["bad.eds is not an EDS canopen can read", "run `make build`, or give --eds"],
    ),
    "bad table": (with_file("--table", "bad.toml", "[node\n", "fields"), EXIT_USAGE, ["bad.toml"]),
    "unknown configured interface": (
        configured_interface("socketcn"),
        EXIT_USAGE,
        ["python-can's configuration", "socketcn"],
    ),
}


@pytest.mark.parametrize("case", list(CASES))
def test_bad_input_is_one_line_with_the_rules_exit_code(
    case: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    setup, expected_code, expected_texts = CASES[case]
    argv = setup(tmp_path, monkeypatch)
    code = main(argv)
    _, err = capsys.readouterr()  # stdout may hold what was decoded before a garbled line
    assert code == expected_code, err
    assert err.count("\n") == 1 and err.startswith("hilrig "), err
    assert "Traceback" not in err
    for text in expected_texts:
        assert text in err


def test_verbose_adds_the_traceback_of_a_handled_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = write("cut.log", CANDUMP_LOG + "(zz) vcan0 12G#\n")(tmp_path)
    code = main(["replay", str(log), "--decode", "-v"])  # -v after the command
    _, err = capsys.readouterr()
    assert code == EXIT_FAILED
    assert err.startswith("Traceback") and err.splitlines()[-1].startswith("hilrig replay: error: ")


def test_replay_reads_gzipped_logs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "bus.log.gz"
    log.write_bytes(gzip.compress(CANDUMP_LOG.encode()))
    code = main(["replay", str(log), "--decode"])
    out, err = capsys.readouterr()
    assert (code, err) == (0, "")
    assert out.split() == ["0.000000", f"0x{SYNC_COB_ID:03X}", "SYNC", "1"]


def test_version_names_hilrig_and_its_libraries(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--version"]) == 0
    out = capsys.readouterr().out
    assert out == version() + "\n"
    assert out.startswith("hilrig ") and "python-can " in out and "canopen " in out and "Python 3." in out


def test_python_m_hilrig_is_the_console_script(tmp_path: Path) -> None:
    txt = write("bus.txt", CANDUMP_LOG)(tmp_path)
    done = subprocess.run(
        [sys.executable, "-m", "hilrig", "replay", str(txt)], capture_output=True, text=True, check=False
    )
    assert done.returncode == EXIT_USAGE
    assert done.stdout == "" and done.stderr.count("\n") == 1
    assert done.stderr.startswith(f"hilrig replay: error: {txt}: python-can reads no .txt files")


def test_help_states_the_exit_code_rule(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    assert "exit codes" in out
    for code in ("  0 ", "  1 ", "  2 ", "  130 "):
        assert code in out


@pytest.mark.skipif(shutil.which("bash") is None, reason="no bash")
@pytest.mark.parametrize(
    ("words", "expected"),
    [
        (["nm"], ["nmt"]),
        (["nmt", "re"], ["reset", "reset-comm"]),
        (["sdo", ""], ["read", "write"]),
        (["sdo", "read", "0x1018", "--ty"], ["--type"]),
        (["sdo", "read", "0x1018", "--type", "u1"], ["u16"]),
        (["get", "-i", "socketc"], ["socketcan", "socketcand"]),
        (["get", "velocity_k"], [n for n in RigTable.load().names if n.startswith("velocity_k")]),
        (["record", "x.log", "--fil"], ["--filter"]),
    ],
)
def test_bash_completion_completes_commands_options_and_choices(
    capsys: pytest.CaptureFixture[str], words: list[str], expected: list[str]
) -> None:
    assert main(["completion", "bash"]) == 0
    script = capsys.readouterr().out
    line = " ".join(["hilrig", *(f"'{w}'" for w in words)])
    complete = f'COMP_WORDS=({line}); COMP_CWORD={len(words)}; _hilrig; printf "%s\\n" "${{COMPREPLY[@]}}"'
    probe = f"{script}\n{complete}\n"
    done = subprocess.run(["bash", "-c", probe], capture_output=True, text=True, check=True)
    assert sorted(done.stdout.split()) == sorted(expected), done.stderr
