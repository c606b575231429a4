"""`hilrig diff` of two bus logs (`hilrig.apps.log_diff`): the first frame that differs, across
formats, times ignored or compared, ids left out; the exit codes."""

from __future__ import annotations

from pathlib import Path

import can
import pytest

from boardproto.cia301 import FunctionCode, cob_id
from hilrig.apps.log_diff import LogComparison, TimeRule, compare_logs
from hilrig.cli import main
from hilrig.session.buslog import whole_file_logger

START = 1_700_000_000.0
TPDO = cob_id(FunctionCode.TPDO1, 0x10)


def frames(n: int = 20, *, shift_s: float = 0.0) -> list[can.Message]:
    return [
        can.Message(
            timestamp=START + shift_s + k * 0.001,
            arbitration_id=TPDO + k % 3,
            data=bytes([k, k ^ 0x55, 0, 1]),
            is_extended_id=False,
        )
        for k in range(n)
    ]


def write(path: Path, messages: list[can.Message]) -> Path:
    with whole_file_logger(path) as logger:
        for message in messages:
            logger.on_message_received(message)
    return path


def test_the_same_frames_agree_and_a_changed_byte_is_the_first_difference() -> None:
    assert compare_logs(frames(), frames()).same
    changed = frames()
    changed[7] = can.Message(
        timestamp=changed[7].timestamp,
        arbitration_id=changed[7].arbitration_id,
        data=b"\x07\x52\x00\x02",
        is_extended_id=False,
    )
    comparison = compare_logs(frames(), changed)
    assert comparison.difference is not None and comparison.difference.number == 8
    assert comparison.frames == 7
    assert comparison.summary() == [
        "bus logs differ at frame 8: data (times ignored)",
        "  BASE  0.007000  0x191 [4] 07 52 00 01",
        "  CAND  0.007000  0x191 [4] 07 52 00 02",
    ]


def test_a_log_that_ends_early_and_an_identifier_differ() -> None:
    short = compare_logs(frames(20), frames(12))
    assert short.summary()[0] == "bus logs differ at frame 13: CAND ends after 12 frames, BASE goes on"
    assert len(short.summary()) == 2
    moved = frames()
    moved[0] = can.Message(
        timestamp=START,
        arbitration_id=cob_id(FunctionCode.TPDO2, 0x10),
        data=moved[0].data,
        is_extended_id=False,
    )
    assert (
        compare_logs(frames(), moved).summary()[0] == "bus logs differ at frame 1: identifier (times ignored)"
    )


def test_times_ignored_relative_or_absolute() -> None:
    later = frames(shift_s=3.0)  # the same run, started 3 s later
    assert compare_logs(frames(), later).same
    assert compare_logs(frames(), later, times=TimeRule.RELATIVE).same
    absolute = compare_logs(frames(), later, times=TimeRule.ABSOLUTE)
    assert absolute.difference is not None and absolute.difference.what == "time, +3.000000 s"
    slower = frames()
    slower[5].timestamp += 2e-6
    relative = compare_logs(frames(), slower, times=TimeRule.RELATIVE)
    assert relative.difference is not None and relative.difference.number == 6
    assert compare_logs(frames(), slower, times=TimeRule.RELATIVE, tolerance_s=5e-6).same


def test_ignored_ids_are_left_out_of_both() -> None:
    fewer = [m for m in frames() if m.arbitration_id != TPDO + 2]
    assert not compare_logs(frames(), fewer).same
    comparison: LogComparison = compare_logs(frames(), fewer, ignore_ids=frozenset({TPDO + 2}))
    assert comparison.same and comparison.frames == len(fewer)


@pytest.mark.parametrize("suffix", [".asc", ".blf", ".mf4"])
def test_diff_command_across_formats(tmp_path: Path, suffix: str, capsys: pytest.CaptureFixture[str]) -> None:
    base = write(tmp_path / "base.log", frames())
    cand = write(tmp_path / f"cand{suffix}", frames())
    assert main(["diff", str(base), str(cand), "--times", "absolute"]) == 0
    assert capsys.readouterr().out == "bus logs agree: 20 frames (times absolute within 1e-06 s)\n"
    changed = frames()
    changed[-1] = can.Message(
        timestamp=changed[-1].timestamp, arbitration_id=0x7FF, data=b"", is_extended_id=False
    )
    write(cand, changed)
    assert main(["diff", str(base), str(cand)]) == 1
    assert (
        capsys.readouterr().out.splitlines()[0] == "bus logs differ at frame 20: identifier (times ignored)"
    )


def test_diff_refuses_a_trace_beside_a_log(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    base = write(tmp_path / "base.log", frames())
    assert main(["diff", str(base), str(base), "-o", str(tmp_path / "x.rrd")]) == 2
    assert "--out, --view and --web are for traces" in capsys.readouterr().err
    assert main(["diff", str(base), str(tmp_path / "missing.blf")]) == 2
    assert "missing.blf" in capsys.readouterr().err
    assert main(["diff", str(base), str(tmp_path / "x.rrd")]) == 2
