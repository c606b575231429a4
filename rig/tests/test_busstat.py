"""`hilrig busstat`: the measured load of a log agrees with `bus-load`'s for the same frames, the
frames per COB-ID, error frames and the TPDO delays after SYNC."""

from __future__ import annotations

from pathlib import Path

import can
import pytest

from boardproto import load_table
from boardproto.cia301 import SYNC_COB_ID, due_at_sync, heartbeat_cob_id
from hilrig.apps.busload import bus_load, frame_bits_worst_case, lockstep_traffic
from hilrig.apps.busstat import measure
from hilrig.cli import main
from hilrig.table import DEFAULT_TABLE_PATH

TABLE = load_table(DEFAULT_TABLE_PATH)
NODE = TABLE.node.default_node_id
RATE_HZ = 1000.0
GAP_S = 20e-6  # between two frames of one cycle


def lockstep_log(cycles: int) -> list[can.Message]:
    """What the rig and the node put on the bus in `cycles` lockstep cycles (no heartbeat): the
    RPDOs, the SYNC, the TPDOs due at it, at 1 kHz; one error frame in the middle."""
    frames: list[can.Message] = []
    rpdos = [p for p in TABLE.rpdos if p.enabled and p.entries]
    tpdos = [p for p in TABLE.tpdos if p.enabled]

    def frame(t: float, cob_id: int, length: int) -> None:
        frames.append(
            can.Message(timestamp=t, arbitration_id=cob_id, data=bytes(length), is_extended_id=False)
        )

    for n in range(1, cycles + 2):  # the last SYNC closes cycle `cycles`
        start = n / RATE_HZ
        for k, pdo in enumerate(rpdos):
            frame(start - (len(rpdos) - k) * GAP_S, pdo.cob_id(NODE), pdo.length_bytes)
        frame(start, SYNC_COB_ID, 1)
        due = [p for p in tpdos if due_at_sync(p.transmission_type, n)]
        for k, pdo in enumerate(due, start=1):
            frame(start + k * GAP_S, pdo.cob_id(NODE), pdo.length_bytes)
        if n == cycles // 2:
            frames.append(can.Message(timestamp=start + 0.5 / RATE_HZ, is_error_frame=True))
    return frames


def test_the_load_per_sync_agrees_with_bus_load_for_the_same_mapping() -> None:
    stats = measure(lockstep_log(200), [p.cob_id(NODE) for p in TABLE.tpdos], RATE_HZ)
    assert (stats.cycles, stats.error_frames) == (200, 1)
    computed = bus_load(
        [t for t in lockstep_traffic(TABLE, RATE_HZ, NODE) if t.name != "heartbeat"], RATE_HZ, 1_000_000
    )
    # The window starts at the first SYNC: the first cycle's RPDOs (before it) are not in it.
    assert stats.load(1_000_000) == pytest.approx(computed.worst_case, rel=0.01)
    assert stats.busiest_cycle_load(1_000_000) == pytest.approx(computed.peak_cycle_worst_case)
    tpdo8 = TABLE.tpdo(8).cob_id(NODE)
    assert stats.per_second(tpdo8) == pytest.approx(RATE_HZ / TABLE.tpdo(8).transmission_type)
    assert stats.by_cob_id[SYNC_COB_ID].bits_worst_case == 200 * frame_bits_worst_case(1)
    tpdo1, tpdo2 = TABLE.tpdo(1).cob_id(NODE), TABLE.tpdo(2).cob_id(NODE)
    assert stats.delays_s[tpdo1] == [pytest.approx(GAP_S)] * 201, "TPDO1 right after its SYNC"
    assert stats.delays_s[tpdo2] == [pytest.approx(2 * GAP_S)] * 201


def test_heartbeats_bunched_into_one_slow_lockstep_cycle_do_not_make_it_the_busiest() -> None:
    # A heartbeat is paced by the node's wall-clock timer: a cycle the host was slow in holds
    # several. They are traffic (the totals have them), but that cycle is no busier on the bus.
    frames = lockstep_log(20)
    quiet = measure(frames, [], RATE_HZ)
    slow_cycle_t = 10 / RATE_HZ + 0.5 / RATE_HZ
    beats = [
        can.Message(timestamp=slow_cycle_t + k * 1e-6, arbitration_id=heartbeat_cob_id(NODE),
                    data=bytes([0x05]), is_extended_id=False)
        for k in range(5)
    ]
    stats = measure(sorted(frames + beats, key=lambda m: m.timestamp), [], RATE_HZ)
    assert stats.busiest_cycle_bits == quiet.busiest_cycle_bits
    assert stats.by_cob_id[heartbeat_cob_id(NODE)].frames == 5
    assert stats.bits_worst_case == quiet.bits_worst_case + 5 * frame_bits_worst_case(1)


def test_the_command_reads_a_log_and_needs_a_bit_rate(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = tmp_path / "bus.log"
    with can.Logger(str(log)) as logger:
        for message in lockstep_log(20):
            logger.on_message_received(message)
    assert main(["busstat", str(log), "-b", "1M", "--rate-hz", "1000"]) == 0
    out, err = capsys.readouterr()
    assert err == ""
    lines = out.splitlines()
    assert lines[1] == "222 frames in 20 SYNC cycles (0.02 s), 1 error frames, 0 remote frames"
    assert lines[2].startswith("load of 1 Mbit/s: ") and "busiest cycle" in lines[2]
    tpdo1 = TABLE.tpdo(1).cob_id(NODE)
    assert f"0x{tpdo1:03X}   TPDO1      20  1000.0          1" in out
    assert f"0x{tpdo1:03X}   TPDO1     21   20      20   20" in out  # delay after SYNC [us], each SYNC
    assert main(["busstat", str(log)]) == 2
    assert capsys.readouterr().err == (
        "hilrig busstat: error: give the bus's bit rate with -b (e.g. -b 1M): the load is a share of it\n"
    )
