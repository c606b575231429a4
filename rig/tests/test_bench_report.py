"""The bench's report (`hilrig.apps.bench.report`, tools/bench.py report): the field recorder's
rows (armed vs idle, armed vs a demo cycle), the Rig's own cycle measured natively
(tools/rig_probe.py), the long run's rows (.rrd size, the web viewer's time to a first drawn
frame), and the long run itself against the in-process fake node (the bus step runs it against
the firmware)."""

from __future__ import annotations

import itertools
import json
import os
import subprocess
import sys
import tracemalloc
from pathlib import Path
from typing import Any

import pytest

from hilrig.apps.bench import baseline as bench_baseline
from hilrig.apps.bench import bus as bench_bus
from hilrig.apps.bench import bus_measure as bench_bus_measure
from hilrig.apps.bench import common as bench_common
from hilrig.apps.bench import main as bench
from hilrig.apps.bench import native as bench_native
from hilrig.apps.bench import probe as bench_probe
from hilrig.apps.bench import report as bench_report


def _rows(ipc: dict[str, float]) -> list[dict[str, Any]]:
    rows = bench_report.ReportRows()
    bench_report._recorder_rows(rows, ipc)
    return rows


def test_the_recorder_is_one_of_the_counted_loops() -> None:
    assert {"recorder_idle", "recorder_armed"} <= set(bench_native.CALLGRIND_LOOPS)


def test_recorder_rows_compare_armed_with_idle_and_with_a_demo_cycle() -> None:
    rows = _rows({"demo": 2000.0, "core": 1.0, "naive": 1.0, "recorder_idle": 7.0, "recorder_armed": 120.0})
    assert [r["measure"] for r in rows] == [
        "instructions/cycle: recorder 8 channels armed vs idle",
        "instructions/cycle: recorder 8 channels armed vs demo joint",
    ]
    assert (rows[0]["ours"], rows[0]["baseline"], rows[0]["goal_met"]) == ("120", "7", True)
    assert rows[1]["ratio"] == 0.06
    assert rows[1]["goal_met"]


def test_recorder_rows_say_when_a_goal_is_missed_and_skip_an_old_run() -> None:
    rows = _rows({"demo": 1000.0, "recorder_idle": 50.0, "recorder_armed": 500.0})
    assert [r["goal_met"] for r in rows] == [False, False]
    assert _rows({"demo": 1000.0, "core": 1.0, "naive": 1.0}) == []


# --- The Rig's own cycle, natively (tools/rig_probe.py) ------------------------------------------
def test_rig_probe_rows_give_the_rigs_instructions_and_its_bytes_kept_per_cycle() -> None:
    rows = bench_report.ReportRows()
    probe = {"rig": 110_000.4, "engine": 55_000.0, "kept_bytes": 550.0, "bus_bytes": 68.8}
    bench_report._rig_probe_rows(rows, probe)
    instructions, kept = rows
    assert instructions["measure"].startswith("instructions/cycle (main thread): Rig lockstep cycle vs")
    assert (instructions["ours"], instructions["baseline"]) == ("110000", "55000")
    assert instructions["ratio"] == pytest.approx(2.0, abs=1e-4)
    assert (kept["ours"], kept["baseline"]) == ("550 B", "69 B")
    empty = bench_report.ReportRows()
    bench_report._rig_probe_rows(empty, None)  # a native.json of an older run, or no valgrind
    assert empty == []


def test_rig_probe_rows_give_what_tracing_costs_per_cycle_next_to_the_rigs_cycle() -> None:
    rows = bench_report.ReportRows()
    probe = {"rig": 110_000.0, "engine": 55_000.0, "tracing": 77_000.4, "kept_bytes": 550.0}
    bench_report._rig_probe_rows(rows, {**probe, "bus_bytes": 68.8})
    _, tracing, kept = rows
    cycles = bench_native.TRACE_PROBE_CYCLES
    assert tracing["measure"] == (
        f"instructions/cycle (all threads): tracing a {cycles}-cycle run vs the Rig's cycle"
    )
    assert (tracing["ours"], tracing["baseline"]) == ("77000", "110000")
    assert tracing["ratio"] == pytest.approx(0.7, abs=1e-4)
    assert kept["measure"].startswith("bytes per lockstep cycle")


def test_rig_probe_rows_give_the_fmu_plants_cycle_beside_the_native_plants() -> None:
    rows = bench_report.ReportRows()
    probe = {"rig": 100_000.0, "engine": 50_000.0, "fmu": 180_000.4, "kept_bytes": 550.0, "bus_bytes": 68.8}
    bench_report._rig_probe_rows(rows, probe)
    _, fmu, _ = rows
    assert fmu["measure"] == (
        "instructions/cycle (main thread): Rig cycle with the joint's FMU (FMPy) vs its native plant"
    )
    assert (fmu["ours"], fmu["baseline"]) == ("180000", "100000")
    assert fmu["ratio"] == pytest.approx(1.8, abs=1e-4)


@pytest.mark.parametrize("mode", ["rig", "fmu", "engine", "traced", "tracer-idle"])
def test_the_rig_probe_runs_its_cycles_against_its_answering_peer(mode: str) -> None:
    probe = bench_probe
    assert probe.main([mode, "30"]) == 0


def test_the_rig_probe_counts_what_the_rig_keeps_and_what_the_bus_carried(capsys) -> None:
    probe = bench_probe
    assert probe.main(["memory", "200"]) == 0
    assert not tracemalloc.is_tracing(), "left on, it slows every later test of this worker 20x"
    kept, on_bus = (float(word) for word in capsys.readouterr().out.split() if word[0].isdigit())
    # The history keeps every PDO's payload and cycle (and the truth), so more than the bus
    # carried, but no per-cycle Python tuples any more: some 550 bytes natively.
    assert on_bus > 0 and on_bus < kept < 20 * on_bus


# --- The long run: .rrd size and time to a first drawn frame -----------------------------------
LONG_TRACE = {"trace": "long-trace/trace.rrd", "bytes": 39_783_276, "cycles": 60_000, "last_cycle": 59_999}


def _long_rows(long_trace: dict[str, Any] | None, first_frame: dict[str, Any]) -> list[dict[str, Any]]:
    rows = bench_report.ReportRows()
    bench_report._long_trace_rows(rows, long_trace, first_frame)
    return rows


def test_long_run_rows_give_the_size_per_cycle_and_the_time_to_a_first_frame() -> None:
    first_frame = {"seconds": 30.07, "dashboard": "overview", "screenshot": "x.png"}
    size, frame = _long_rows(LONG_TRACE, first_frame)
    assert size["measure"] == ".rrd size of a 60 s run at 1 kHz (ratio: bytes per cycle)"
    assert (size["ours"], size["baseline"]) == ("39.8 MB", "60000 cycles")
    assert size["ratio"] == pytest.approx(663.05, abs=0.01)
    assert size["data"]["trace"] == "long-trace/trace.rrd"
    assert frame["measure"] == "time to first drawn frame (web viewer, headless Chromium, software WebGL)"
    assert (frame["ours"], frame["baseline"], frame["ratio"]) == ("30.1 s", "60000 cycles, overview", None)


def test_long_run_rows_say_why_when_there_is_no_browser_or_no_long_run() -> None:
    no_chromium = {"error": "no /usr/bin/chromium: apt-get install chromium (tools/deps)"}
    size, frame = _long_rows(LONG_TRACE, no_chromium)
    assert size["ours"] == "39.8 MB"
    assert (frame["ours"], frame["baseline"]) == ("not measured", no_chromium["error"])
    size, frame = _long_rows(None, bench_report.measure_first_frame(Path("/nonexistent"), None))
    assert (size["ours"], size["baseline"]) == ("not measured", bench_report.NO_LONG_TRACE)
    assert (frame["ours"], frame["baseline"]) == ("not measured", bench_report.NO_LONG_TRACE)


def test_the_first_frame_is_not_measured_without_the_trace(tmp_path: Path) -> None:
    assert bench_report.measure_first_frame(tmp_path, LONG_TRACE) == {
        "error": f"no trace at {tmp_path / 'long-trace' / 'trace.rrd'}"
    }


def _bus_json(**extra: Any) -> dict[str, Any]:
    """A bus.json with what every other row needs, and `extra`."""
    rates = {f"{kind}_cycles_per_s": [900.0] for kind in ("rig", "rig_traced", "floor", "python_can")}
    return {
        "bus_path": "native vcan",
        "lockstep": rates,
        "sdo": {"firmware": {"median_us": 100.0}, "local_node": {"median_us": 400.0}},
        "bus_load": {
            "frames_per_cycle": 6.0,
            "loads": [{"bitrate": 1_000_000, "nominal": 0.5, "worst_case": 0.6, "busiest_cycle": 0.6}],
        },
        "free_running": {
            "period_us": 1000,
            "abs_error_us": {"50": 5.0, "99": 50.0, "max": 90.0},
            "method": "fixed",
            "cycles": 10,
            "mean_period_us": 1000.0,
            "late_by_half_a_period": 0,
            "firmware_overruns": 0,
        },
        **extra,
    }


def _report(out: Path, bus: dict[str, Any]) -> list[dict[str, Any]]:
    """`tools/bench.py report` on a fixed native.json and this bus.json: the long run's rows."""
    machine = {"cpu": "cpu", "cores": 2, "kernel": "6"}
    native = {"date": "today", "machine": machine, "board_bench_ns": {}, "callgrind": None}
    (out / "native.json").write_text(json.dumps(native))
    (out / "bus.json").write_text(json.dumps(bus))
    assert bench.main(["report", "--out", str(out)]) == 0
    report = json.loads((out / "report.json").read_text())
    return [r for r in report["rows"] if "rrd size" in r["measure"] or "first drawn frame" in r["measure"]]


def test_the_report_without_a_long_run_still_comes_whole(tmp_path: Path) -> None:
    """A bus.json from before the long run: the report is written, its rows say so."""
    rows = _report(tmp_path, _bus_json())
    assert [(r["ours"], r["baseline"]) for r in rows] == [("not measured", bench_report.NO_LONG_TRACE)] * 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bus.json", "native.json", "report.json"]


def test_the_report_without_chromium_gives_the_size_and_says_what_to_install(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import hilrig.observe.browser

    monkeypatch.setattr(hilrig.observe.browser, "CHROMIUM", tmp_path / "no-chromium")
    (tmp_path / "long-trace").mkdir()
    (tmp_path / "long-trace" / "trace.rrd").write_bytes(bytes(100))  # never opened: no browser
    size, frame = _report(tmp_path, _bus_json(long_trace=LONG_TRACE))
    assert size["ours"] == "39.8 MB"
    assert frame["ours"] == "not measured"
    assert frame["baseline"] == f"no {tmp_path / 'no-chromium'}: apt-get install chromium (tools/deps)"


def _fake_node_run(out: Path, cycles: int) -> dict[str, Any]:
    """traced_run through the session's real-board path: the rig on a python-can virtual bus,
    the in-process fake node answering each SYNC; the trace in out/long-trace/."""
    import can

    from hilrig.session.fake_node import FakeJointNode
    from hilrig.session.run import BoardInterface, BusRun, RunDescription, TraceRun
    from hilrig.table import RigTable

    table = RigTable.load()
    channel = f"bench-long-{os.getpid()}"
    fake_bus = can.Bus(interface="virtual", channel=channel)
    fake = FakeJointNode(fake_bus, table=table)
    fake.boot()
    try:
        run = RunDescription(
            TraceRun(out / bench_bus_measure.LONG_TRACE_DIR, trace=True, record=False),
            bus=BusRun(board=BoardInterface("virtual", channel)),
        )
        return bench_bus_measure.traced_run(run, cycles, table)
    finally:
        fake.close()
        fake_bus.shutdown()


def test_the_long_run_writes_a_whole_trace_against_the_fake_node(tmp_path: Path) -> None:
    from hilrig.observe.reader import Trace

    cycles = 2 * round(bench_bus_measure.LONG_TRACE_STEP_S * 1000) + 100  # two setpoint flips
    run = _fake_node_run(tmp_path, cycles)
    trace = tmp_path / bench_bus_measure.LONG_TRACE_DIR / "trace.rrd"
    assert (run["trace"], run["cycles"], run["last_cycle"]) == (str(trace), cycles, cycles - 1)
    assert run["bytes"] == trace.stat().st_size
    setpoints = Trace.read(trace).scalars["/fields/commands/velocity_setpoint"]
    assert len(setpoints) == cycles
    flips = sum(1 for a, b in itertools.pairwise(setpoints) if a != b)
    assert flips == 2, "the setpoint flips sign every LONG_TRACE_STEP_S"


@pytest.mark.timeout(600)
def test_the_report_step_measures_the_first_frame_of_the_long_runs_trace(tmp_path: Path) -> None:
    """measure_first_frame as the report step calls it (the path relative to the bench folder),
    on a short run: a time, and the screenshot it stopped at has the overview's plots drawn."""
    from PIL import Image

    from hilrig.observe.browser import PLOTTED_PIXELS, browser_missing, plotted_pixels

    if browser_missing() is not None:
        pytest.skip(str(browser_missing()))
    run = _fake_node_run(tmp_path, 300)
    long_trace = run | {"trace": str(Path(run["trace"]).relative_to(tmp_path))}
    first_frame = bench_report.measure_first_frame(tmp_path, long_trace)
    assert first_frame.get("seconds", 0) > 0, first_frame
    with Image.open(first_frame["screenshot"]) as screenshot:
        assert plotted_pixels(screenshot) > PLOTTED_PIXELS


def test_lockstep_rows_put_the_rig_against_both_floors_and_read_an_older_run(tmp_path: Path) -> None:
    def lockstep_rows(bus: dict[str, Any]) -> dict[str, tuple[str, str, float]]:
        _report(tmp_path, bus)
        report = json.loads((tmp_path / "report.json").read_text())
        return {
            r["measure"]: (r["ours"], r["baseline"], r["ratio"])
            for r in report["rows"]
            if "lockstep" in r["measure"]
        }

    bus = _bus_json()
    bus["lockstep"] |= {
        "rig_cycles_per_s": [500.0, 600.0],
        "floor_cycles_per_s": [1200.0],
        "engine_floor_cycles_per_s": [1500.0],
    }
    rows = lockstep_rows(bus)
    assert rows["lockstep cycles/s: Rig untraced vs raw-socket floor"] == ("600/s", "1200/s", 0.5)
    assert rows["lockstep cycles/s: Rig untraced vs the engine's exchange alone (C, no physics/history)"] == (
        "600/s",
        "1500/s",
        0.4,
    )
    assert rows["lockstep cycles/s: the engine's exchange alone vs raw-socket floor"] == (
        "1500/s",
        "1200/s",
        1.25,
    )
    paired = "lockstep cycles/s: Rig traced vs untraced, median of the runs paired back to back"
    best_of_each = "lockstep cycles/s: Rig traced vs untraced, best of each"
    assert paired not in rows  # 2 untraced runs, 1 traced: not paired
    assert rows[best_of_each] == ("900/s", "600/s", 1.5)  # the goal on the best of each instead
    bus["lockstep"] |= {
        "rig_cycles_per_s": [1000.0, 2000.0, 1500.0],
        "rig_traced_cycles_per_s": [800.0, 1500.0, 1350.0],
    }
    rows = lockstep_rows(bus)
    assert rows[paired] == ("0.75..0.90", "3 pairs", 0.8)
    assert rows[best_of_each] == ("1500/s", "2000/s", 0.75)
    goals = {r["measure"]: r["goal_met"] for r in json.loads((tmp_path / "report.json").read_text())["rows"]}
    assert goals[paired] is True and goals[best_of_each] is None  # the pairs decide
    older = lockstep_rows(_bus_json())  # a bus.json from before the engine's floor was measured
    assert not any("engine" in measure for measure in older)
    assert "lockstep cycles/s: Rig untraced vs raw-socket floor" in older


def test_each_round_pairs_the_rigs_runs_both_ways_round() -> None:
    for round_ in range(1, bench_bus.LOCKSTEP_ROUNDS + 1):
        orders = bench_bus.rig_pair_orders(round_)
        assert len(orders) == bench_bus.RIG_PAIRS_PER_ROUND
        assert all(sorted(order) == ["rig", "rig_traced"] for order in orders)
        firsts = [order[0] for order in orders]
        assert firsts.count("rig") == firsts.count("rig_traced")  # each kind first in half
    # Mirrored in even rounds: each kind also runs first after the previous round's floors.
    assert bench_bus.rig_pair_orders(1)[0] == ("rig", "rig_traced")
    assert bench_bus.rig_pair_orders(2)[0] == ("rig_traced", "rig")
    assert bench_bus.rig_pair_orders(2) == bench_bus.rig_pair_orders(1)[::-1]


# --- A probe that fails costs its own row, never the report --------------------------------------
SLOW_PROBE = "raise SystemExit('never started: the test has subprocess.run time it out')"
"""The command of a probe the test times out by patching subprocess.run (no wall clock)."""
FAILING_PROBE = "import sys; print('valgrind: out of memory', file=sys.stderr); sys.exit(3)"


def test_a_probe_that_times_out_or_fails_says_so_with_the_end_of_its_stderr() -> None:
    # The shell writes its line at once; the timeout is long enough for a loaded host to start it.
    slow_shell = ["sh", "-c", "echo 'callgrind: still counting' >&2; exec sleep 60"]
    with pytest.raises(bench_common.ProbeError) as timed_out:
        bench_common.run_probe(slow_shell, timeout_s=3.0)
    assert "timed out after 3 s" in str(timed_out.value)
    assert "callgrind: still counting" in str(timed_out.value)
    with pytest.raises(bench_common.ProbeError) as failed:
        bench_common.run_probe([sys.executable, "-c", FAILING_PROBE])
    assert "exit status 3" in str(failed.value) and "valgrind: out of memory" in str(failed.value)
    with pytest.raises(bench_common.ProbeError, match="could not start"):
        bench_common.run_probe(["/nonexistent/fw_board_bench"])


def _native_step_with_a_rig_probe_that_times_out(out: Path, monkeypatch: pytest.MonkeyPatch) -> int:
    """`tools/bench.py native` where fw_board_bench is not built, the callgrind counts are
    stand-ins, and rig_probe.py under callgrind times out for the checkout's Rig cycle (not for
    the baseline's, a stand-in tree)."""
    baseline_tree = out / "baseline" / ("ab" * 20)

    def timed_out(command: list[str], **options: object) -> None:
        # What subprocess.run raises for a probe past its timeout: no wall clock in this test.
        raise subprocess.TimeoutExpired(command, 0.5, stderr="callgrind: still counting\n")

    def rig_probe_instructions(
        mode: str, cycles: int, *, all_threads: bool = False, root: Path = bench_common.ROOT
    ) -> int:
        if mode == "rig" and root != baseline_tree:
            with pytest.MonkeyPatch.context() as probe_patch:
                probe_patch.setattr(bench_common.subprocess, "run", timed_out)
                bench_common.run_probe([sys.executable, "-c", SLOW_PROBE], timeout_s=0.5)
        return cycles * 1000

    monkeypatch.setattr(bench_native, "prepare_checkout", lambda: None)
    monkeypatch.setattr(bench_baseline, "prepare_baseline", lambda out, commit: baseline_tree)
    monkeypatch.setattr(bench_native.shutil, "which", lambda name: f"/usr/bin/{name}")
    monkeypatch.setattr(bench_native, "callgrind_instructions", lambda out, loop, cycles: 100 + cycles * 2000)
    monkeypatch.setattr(bench_native, "rig_probe_instructions", rig_probe_instructions)
    monkeypatch.setattr(bench_native, "_rig_memory_per_cycle", lambda: (550.0, 68.8))
    virt_size = {"image": "joint-firmware-virt.elf", "flash_bytes": 64 * 1024, "flash_budget": 512 * 1024}
    virt_size |= {"ram_bytes": 120 * 1024, "ram_budget": 256 * 1024}
    monkeypatch.setattr(bench_native, "virt_size", lambda: virt_size)
    monkeypatch.setattr(
        bench_native,
        "virt_cycle_cost",
        lambda: {"cycles": 2000, "instructions_per_cycle": 1200.0, "worst": 1280},
    )
    return bench.main(["native", "--out", str(out)])


def _report_rows(out: Path) -> dict[str, dict[str, Any]]:
    return {r["measure"]: r for r in json.loads((out / "report.json").read_text())["rows"]}


def test_a_failing_probe_is_a_row_not_measured_and_the_report_is_still_written(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    assert _native_step_with_a_rig_probe_that_times_out(tmp_path, monkeypatch) == 0
    native = json.loads((tmp_path / "native.json").read_text())
    assert set(native["not_measured"]) == {"board_bench", "rig_probe rig"}
    assert "timed out after 0.5 s" in native["not_measured"]["rig_probe rig"]
    (tmp_path / "bus.json").write_text(json.dumps(_bus_json()))
    assert bench.main(["report", "--out", str(tmp_path)]) == 0
    rows = _report_rows(tmp_path)
    rig_cycle = rows["instructions/cycle (main thread): Rig lockstep cycle vs the engine's exchange alone"]
    assert rig_cycle["ours"] == "not measured"
    assert rig_cycle["baseline"].endswith("timed out after 0.5 s")
    assert "callgrind: still counting" in rig_cycle["data"]["error"]  # the probe's stderr tail
    board = rows["board get (vs raw array)"]
    assert board["ours"] == "not measured" and "could not start" in board["data"]["error"]
    # Every other figure is there: the probes that worked, and the bus part.
    assert (
        rows["bytes per lockstep cycle: kept by the Rig (history) vs the data on the bus"]["ours"] == "550 B"
    )
    assert rows["instructions/cycle: demo joint vs stand-ins on naive board"]["ours"] == "2000"
    virt = rows[
        "instructions/cycle: bare-metal image under qemu -icount vs the Linux firmware under callgrind"
    ]
    assert (virt["ours"], virt["baseline"], virt["ratio"]) == ("1200 (worst 1280)", "2000", 0.6)
    assert rows["lockstep cycles/s: Rig untraced vs raw-socket floor"]["ours"] == "900/s"
    # Against the baseline: the Rig's row says why the checkout's count is missing, the engine's
    # compares both trees' counts.
    rig_vs_old, engine_vs_old = (rows[m] for m in rows if "this checkout vs baseline abababab" in m)
    assert rig_vs_old["ours"] == "not measured" and rig_vs_old["baseline"].endswith("timed out after 0.5 s")
    assert (engine_vs_old["ours"], engine_vs_old["baseline"]) == ("1000", "1000")
    assert engine_vs_old["goal_met"] is True
    assert not list(tmp_path.glob(".report.json.*"))  # written atomically: no temporary left


def test_the_printed_report_ends_with_each_failed_probes_whole_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    _native_step_with_a_rig_probe_that_times_out(tmp_path, monkeypatch)
    (tmp_path / "bus.json").write_text(json.dumps(_bus_json()))
    capsys.readouterr()
    bench.main(["report", "--out", str(tmp_path)])
    printed = capsys.readouterr().out
    assert "not measured: instructions/cycle (main thread): Rig lockstep cycle" in printed
    assert "    stderr (end):" in printed and "callgrind: still counting" in printed


def test_a_bus_section_that_cannot_be_read_costs_only_its_own_row(tmp_path: Path) -> None:
    bus = _bus_json()
    del bus["sdo"]["local_node"]  # a bus.json whose SDO part broke off
    bus["not_measured"] = {"free_running": "free_running: the firmware never reached operational"}
    del bus["free_running"]
    _report(tmp_path, bus)
    rows = _report_rows(tmp_path)
    sdo = rows[bench_report.SECTION_TITLES["sdo"]]
    assert (sdo["ours"], sdo["baseline"]) == ("not measured", "KeyError: 'local_node'")
    assert not any(measure.startswith("SDO server turnaround") for measure in rows)  # dropped whole
    free = rows[bench_report.SECTION_TITLES["free_running"]]
    assert free["baseline"] == "free_running: the firmware never reached operational"
    assert rows["lockstep cycles/s: Rig untraced vs raw-socket floor"]["ours"] == "900/s"


def test_a_missing_part_still_gives_a_report_and_a_failed_exit(tmp_path: Path) -> None:
    machine = {"cpu": "cpu", "cores": 2, "kernel": "6"}
    native = {"date": "today", "machine": machine, "board_bench_ns": {}, "callgrind": None}
    (tmp_path / "native.json").write_text(json.dumps(native))  # no bus.json: the VM step died
    assert bench.main(["report", "--out", str(tmp_path)]) == 1
    lockstep = _report_rows(tmp_path)[bench_report.SECTION_TITLES["lockstep"]]
    assert lockstep["ours"] == "not measured"
    assert "bus.json is unreadable" in lockstep["baseline"]
    assert "the bus step did not finish" in lockstep["baseline"]


def test_robot_rows_put_each_robot_against_its_n_node_floor_and_judge_the_cost_per_module(
    tmp_path: Path,
) -> None:
    bus = _bus_json(
        robot={
            "cycles": 500,
            "cycles_per_s": {"1": [600.0, 700.0], "4": [200.0], "8": [100.0], "16": [40.0]},
            "floor_cycles_per_s": {"1": [1000.0], "4": [400.0], "8": [180.0], "16": [100.0]},
        }
    )
    _report(tmp_path, bus)
    rows = _report_rows(tmp_path)
    floor16 = rows["robot lockstep cycles/s, 16 modules: robot vs raw 16-node floor"]
    assert (floor16["ours"], floor16["baseline"], floor16["ratio"]) == ("40/s", "100/s", 0.4)
    assert floor16["goal"] == ">= 0.5" and floor16["goal_met"] is False
    assert rows["robot lockstep cycles/s, 4 modules: robot vs raw 4-node floor"]["goal_met"] is True
    cost16 = rows["robot lockstep cycles/s, 16 modules vs 1 (cycle cost ratio)"]
    assert cost16["ratio"] == 700.0 / 40.0
    assert cost16["goal"] == f"{700.0 / 40.0 / 16:.2f}x per module (goal <= 1.2)"
    assert cost16["goal_met"] is (700.0 / 40.0 / 16 <= 1.2)
    assert rows["robot lockstep cycles/s, 8 modules vs 1 (cycle cost ratio)"]["goal_met"] is None
    floor_growth = rows["raw N-node floor cycles/s, 16 modules vs 1 (cost per module)"]
    assert floor_growth["ratio"] == 1000.0 / 100.0 / 16
    older = _bus_json(robot={"cycles": 500, "cycles_per_s": {"1": [700.0], "8": [47.0]}})  # no floor yet
    _report(tmp_path, older)
    rows = _report_rows(tmp_path)
    assert not any("floor" in measure for measure in rows if measure.startswith("robot"))
    assert rows["robot lockstep cycles/s, 8 modules vs 1 (cycle cost ratio)"]["ours"] == "47/s"


def test_the_rig_probe_runs_a_robot_of_several_modules_against_answering_peers() -> None:
    probe = bench_probe
    assert probe.main(["robot", "30", "--modules", "3"]) == 0
