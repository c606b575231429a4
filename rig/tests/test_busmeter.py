"""The bus measurements a trace holds (`hilrig.observe.busmeter`): load per 10 ms window, each
TPDO's delay after its SYNC, late / missing / malformed TPDOs and error frames; from a hand-made
candump log through `hilrig replay LOG --trace`, and from the meter alone."""

from __future__ import annotations

from pathlib import Path

import pytest

from boardproto.cia301 import SYNC_COB_ID
from hilrig.cli import main
from hilrig.observe.busmeter import BusMeter, PdoSpec
from hilrig.observe.paths import BUS_EVENTS_PATH, BUS_LOAD_PATH, BusProblem, delay_path, problem_path
from hilrig.observe.reader import Trace
from hilrig.table import RigTable
from hilrig.wire.framebits import frame_bits_worst_case

T0 = 1_700_000_000.0
PERIOD_S = 0.001
CYCLES = 25
TPDO_AFTER_SYNC_S = 0.0002
MALFORMED_AT, ERROR_AT, TWICE_AT, SILENT_AT = 5, 10, 15, 20
"""Cycles of the log below: TPDO1 one byte short; an error frame; TPDO1 twice; no TPDO1."""


def _candump(path: Path, tpdo1: int, length: int) -> list[tuple[float, int]]:
    """Write the log; return (time, data bytes) of every data frame, for the expected load."""
    lines: list[str] = []
    frames: list[tuple[float, int]] = []

    def frame(t: float, cob_id: int, data: bytes) -> None:
        lines.append(f"({t:.6f}) can0 {cob_id:03X}#{data.hex().upper()}")
        frames.append((t, len(data)))

    for cycle in range(CYCLES):
        sync_t = T0 + cycle * PERIOD_S
        frame(sync_t, SYNC_COB_ID, bytes([cycle % 240 + 1]))
        tpdo_t = sync_t + TPDO_AFTER_SYNC_S
        if cycle == MALFORMED_AT:
            frame(tpdo_t, tpdo1, bytes(length - 1))
        elif cycle == ERROR_AT:
            lines.append(f"({tpdo_t - 0.0001:.6f}) can0 20000080#0000000000000000")
            frame(tpdo_t, tpdo1, bytes(length))
        elif cycle == TWICE_AT:
            frame(tpdo_t, tpdo1, bytes(length))
            frame(tpdo_t + 0.0003, tpdo1, bytes(length))
        elif cycle != SILENT_AT:
            frame(tpdo_t, tpdo1, bytes(length))
    path.write_text("\n".join(lines) + "\n")
    return frames


def test_replay_of_a_bus_log_traces_its_load_delays_and_problems(tmp_path: Path) -> None:
    board = RigTable.load().board
    node_id = board.node.default_node_id
    tpdo = board.tpdo(1)
    assert tpdo.transmission_type == 1, "the log below sends TPDO1 every SYNC"
    log, rrd = tmp_path / "bus.log", tmp_path / "bus.rrd"
    frames = _candump(log, tpdo.cob_id(node_id), tpdo.length_bytes)

    assert main(["replay", str(log), "--trace", str(rrd)]) == 0
    trace = Trace.read(rrd)

    # Load: the worst-case bits of each 10 ms window's frames over 10 ms at 1 Mbit/s, in %.
    windows = [0.0, 0.0, 0.0]
    for t, data_bytes in frames:
        windows[int((t - T0) / 0.010 + 1e-9)] += frame_bits_worst_case(data_bytes)
    expected_load = [bits / (0.010 * 1_000_000) * 100 for bits in windows]
    assert trace.scalars[BUS_LOAD_PATH] == pytest.approx(expected_load)
    assert trace.times[BUS_LOAD_PATH] == pytest.approx([T0, T0 + 0.010, T0 + 0.020])

    # Delays by the log's timestamps (to the microsecond a Unix time in a double keeps): 0.2 ms
    # after each SYNC, the second of the pair 0.5 ms; none for the malformed one or cycle 20.
    delays = trace.scalars[delay_path("TPDO1")]
    assert len(delays) == CYCLES - 2 + 1
    assert sorted(delays) == pytest.approx([0.2] * (CYCLES - 2) + [0.5], abs=1e-3)

    # Counts so far at each window, and one event each.
    counts = {p: trace.scalars[problem_path(p)] for p in BusProblem}
    assert counts[BusProblem.MALFORMED] == [1, 1, 1]
    assert counts[BusProblem.ERROR_FRAME] == [0, 1, 1]
    assert counts[BusProblem.LATE] == [0, 1, 1]
    # The malformed one counts as not come (missing at SYNC 5), and so does the silent cycle 20
    # (said at the next SYNC: the last window).
    assert counts[BusProblem.MISSING] == [1, 1, 2]
    texts = [text for text, _ in trace.texts[BUS_EVENTS_PATH]]
    assert len(texts) == 5, texts
    assert any("TPDO1 (0x190) malformed: 2 bytes, its mapping has 3" in text for text in texts)
    assert any(text.startswith("error frame at t = ") for text in texts)
    assert "TPDO1 late: a second one after SYNC 15" in texts
    assert {"TPDO1 missing at SYNC 5", "TPDO1 missing at SYNC 20"} <= set(texts)


def test_a_quiet_window_is_0_percent_and_a_tpdo_every_10th_sync_is_not_missing_in_between() -> None:
    board = RigTable.load().board
    tpdo8 = board.tpdo(8).cob_id(board.node.default_node_id)
    tpdo = PdoSpec("TPDO8", 8, tpdo=True, transmission_type=10)
    meter = BusMeter({tpdo8: tpdo}, bitrate=500_000)
    for cycle in range(31):
        meter.frame(cycle * 0.001, cycle, SYNC_COB_ID, 1)
        if cycle % 10 == 0:
            meter.frame(cycle * 0.001 + 0.0001, cycle, tpdo8, 8)
    meter.frame(0.055, 30, SYNC_COB_ID, 1)  # after 25 ms of silence
    measured = meter.take(final=True)
    per_window = (10 * frame_bits_worst_case(1) + frame_bits_worst_case(8)) / (0.010 * 500_000) * 100
    assert measured.load[:3] == pytest.approx([per_window] * 3)
    assert measured.load[4] == 0.0  # 40..50 ms: nothing on the bus
    assert measured.window_times[3:6] == pytest.approx([0.030, 0.040, 0.050])
    assert measured.load[5] == pytest.approx(frame_bits_worst_case(1) / (0.010 * 500_000) * 100)
    assert meter.totals == dict.fromkeys(BusProblem, 0)
    assert measured.delays["TPDO8"][2] == pytest.approx([0.1] * 4)


def test_a_bitrate_of_0_is_refused() -> None:
    with pytest.raises(ValueError, match="bitrate"):
        BusMeter({}, bitrate=0)
