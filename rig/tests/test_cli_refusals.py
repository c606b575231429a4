"""Bad inputs of the command line, each answered in one line with the exit code of
`hilrig --help`'s rule (2: refused before anything ran; 1: it ran and failed), natively: a
trace that is none or a port out of range, an output into a folder that does not exist or onto a
folder (none is created), a folder given as a log, a write to a field the table marks read-only
(refused here, nothing sent), a silent bus under `sim --board` (said at once, bounded), a
vendor library that is not installed, no display for a native viewer."""

from __future__ import annotations

import ctypes.util
from pathlib import Path

import can
import pytest

from hilrig.cli import EXIT_FAILED, EXIT_OK, EXIT_USAGE, main

CANDUMP_LOG = "(1700000000.000000) vcan0 080#01\n"
RRD_START = b"RRF2"  # how a Rerun recording starts (a whole one is not needed to refuse the rest)


def one_line(capsys: pytest.CaptureFixture[str], argv: list[str]) -> tuple[int, str]:
    code = main(argv)
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert err.count("\n") == 1 and err.startswith("hilrig "), err
    return code, err


@pytest.fixture
def display(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("DISPLAY", ":0")


def test_view_check_of_a_file_that_is_no_recording(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    trace = tmp_path / "notrrd.rrd"
    trace.write_text("not a recording\n")
    code, err = one_line(capsys, ["view", str(trace), "--check"])
    assert code == EXIT_USAGE
    assert "notrrd.rrd is not a Rerun recording" in err


def test_view_check_of_a_recording_cut_off_is_content_that_cannot_be_read(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    trace = tmp_path / "cut.rrd"
    trace.write_bytes(RRD_START + b"\x00")
    code, err = main(["view", str(trace), "--check"]), capsys.readouterr().err
    assert code == EXIT_FAILED  # the rule: a file whose content cannot be parsed
    assert err.splitlines()[-1].startswith(f"hilrig view: error: {trace}: Rerun cannot read this recording")
    assert "Traceback" not in err


@pytest.mark.parametrize("option", ["--web", "--grpc-port"])
def test_view_port_out_of_range(
    option: str, tmp_path: Path, capsys: pytest.CaptureFixture[str], display: None
) -> None:
    trace = tmp_path / "t.rrd"
    trace.write_bytes(RRD_START)
    code, err = one_line(capsys, ["view", str(trace), option, "99999"])
    assert code == EXIT_USAGE
    assert "expected a TCP port 1..65535, got '99999'" in err


def test_view_without_a_display_suggests_web(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    for name in ("DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET"):
        monkeypatch.delenv(name, raising=False)
    trace = tmp_path / "t.rrd"
    trace.write_bytes(RRD_START)
    code, err = one_line(capsys, ["view", str(trace)])
    assert code == EXIT_USAGE
    assert "no display" in err and "add --web" in err


def test_dbc_onto_a_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, err = one_line(capsys, ["dbc", "-o", str(tmp_path)])
    assert code == EXIT_USAGE
    assert f"DBC {tmp_path} is a directory" in err
    assert "Errno" not in err


@pytest.mark.parametrize(
    "argv",
    [
        ["dbc", "-o", "{missing}/board.dbc"],
        ["record", "{missing}/bus.log", "-i", "virtual", "-c", "refusals-record"],
        ["replay", "{log}", "--trace", "{missing}/x.rrd"],
    ],
    ids=["dbc", "record", "replay --trace"],
)
def test_output_into_a_folder_that_does_not_exist_creates_none(
    argv: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = tmp_path / "bus.log"
    log.write_text(CANDUMP_LOG)
    missing = tmp_path / "nope" / "deeper"
    code, err = one_line(capsys, [a.format(missing=missing, log=log) for a in argv])
    assert code == EXIT_USAGE
    assert f"folder {missing} does not exist" in err
    assert not (tmp_path / "nope").exists()


def test_replay_trace_under_proc(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "bus.log"
    log.write_text(CANDUMP_LOG)
    code, err = one_line(capsys, ["replay", "--trace", "/proc/nope/x.rrd", str(log)])
    assert code == EXIT_USAGE
    assert "folder /proc/nope does not exist" in err and "Errno" not in err


def test_replay_of_a_folder_says_it_is_one(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, err = one_line(capsys, ["replay", str(tmp_path)])
    assert code == EXIT_USAGE
    assert f"log {tmp_path} is a directory, not a file" in err
    assert "does not exist" not in err


def test_set_of_a_read_only_field_is_refused_before_anything_is_sent(
    channel: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with can.Bus(interface="virtual", channel=channel) as listener:
        code, err = one_line(
            capsys, ["set", "velocity_kp=0.2", "motor_velocity=1", "-i", "virtual", "-c", channel]
        )
        assert listener.recv(timeout=0) is None  # not even velocity_kp, which comes first
    assert code == EXIT_USAGE
    assert "motor_velocity: read-only over the bus" in err


def test_sim_board_on_a_silent_bus_says_what_it_waits_for_and_gives_up(
    channel: str, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import hilrig.apps.demo

    monkeypatch.setattr(hilrig.apps.demo, "BOARD_SILENT_S", 0.2)
    argv = ["sim", "--board", "-i", "virtual", "-c", channel, "--no-trace", "--out", str(tmp_path)]
    code = main(argv)
    lines = capsys.readouterr().err.splitlines()
    assert code == EXIT_FAILED
    assert "waiting up to 0.2 s for its heartbeat" in lines[0]
    assert lines[-1].startswith("hilrig sim: error: node 0x10: no boot-up or heartbeat within 0.2 s")
    assert len(lines) == 2


def test_plain_bus_load_explains_with_the_rules_exit_code(capsys: pytest.CaptureFixture[str]) -> None:
    """The first example of its help: the survey of the standard bit rates, done (0)."""
    code = main(["bus-load"])
    err = capsys.readouterr().err
    assert code == EXIT_OK, err
    assert "Traceback" not in err


@pytest.mark.parametrize(
    ("interface", "library", "channel"),
    [("pcan", "pcanbasic", "PCAN_USBBUS1"), ("kvaser", "canlib", "0")],
)
def test_a_missing_vendor_library_is_a_usage_error_saying_what_to_install(
    interface: str, library: str, channel: str, capsys: pytest.CaptureFixture[str]
) -> None:
    if ctypes.util.find_library(library) is not None:
        pytest.skip(f"lib{library} is installed here")
    code, err = one_line(capsys, ["scan", "-i", interface, "-c", channel, "--listen", "0.1"])
    assert code == EXIT_USAGE
    assert f"cannot use the {interface} interface: it needs " in err and "which is not installed" in err
    assert "NameError" not in err and "is not defined" not in err
