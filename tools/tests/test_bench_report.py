"""tools/bench.py's report: the field recorder's rows (armed vs idle, armed vs a demo cycle); the
long traced run against the in-process fake node (the bus step runs it against the firmware)."""

from __future__ import annotations

import importlib.util
import itertools
import os
import sys
from pathlib import Path
from types import ModuleType
from typing import Any


def load_tool(name: str) -> ModuleType:
    path = Path(__file__).resolve().parent.parent / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


bench = load_tool("bench")


def _rows(ipc: dict[str, float]) -> list[dict[str, Any]]:
    rows = bench.ReportRows()
    bench._recorder_rows(rows, ipc)
    return rows


def test_the_recorder_is_one_of_the_counted_loops() -> None:
    assert {"recorder_idle", "recorder_armed"} <= set(bench.CALLGRIND_LOOPS)


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


# --- The long run -------------------------------------------------------------------------------
def _fake_node_run(out: Path, cycles: int) -> dict[str, Any]:
    """traced_run through the session's real-board path: the rig on a python-can virtual bus,
    the in-process fake node answering each SYNC; the trace in out/long-trace/."""
    import can

    from hilrig.fake_node import FakeJointNode
    from hilrig.session import BoardInterface, SessionConfig
    from hilrig.table import RigTable

    table = RigTable.load()
    channel = f"bench-long-{os.getpid()}"
    fake_bus = can.Bus(interface="virtual", channel=channel)
    fake = FakeJointNode(fake_bus, table=table)
    fake.boot()
    try:
        config = SessionConfig(
            out_dir=out / bench.LONG_TRACE_DIR,
            trace=True,
            record=False,
            board=BoardInterface("virtual", channel),
            node_id=table.board.node.default_node_id,
            period_us=bench.PERIOD_US,
        )
        return bench.traced_run(config, cycles, table)
    finally:
        fake.close()
        fake_bus.shutdown()


def test_the_long_run_writes_a_whole_trace_against_the_fake_node(tmp_path: Path) -> None:
    from hilrig.trace_reader import Trace

    cycles = 2 * round(bench.LONG_TRACE_STEP_S * 1000) + 100  # two setpoint flips
    run = _fake_node_run(tmp_path, cycles)
    trace = tmp_path / bench.LONG_TRACE_DIR / "trace.rrd"
    assert (run["trace"], run["cycles"], run["last_cycle"]) == (str(trace), cycles, cycles - 1)
    assert run["bytes"] == trace.stat().st_size
    setpoints = Trace.read(trace).scalars["/fields/commands/velocity_setpoint"]
    assert len(setpoints) == cycles
    flips = sum(1 for a, b in itertools.pairwise(setpoints) if a != b)
    assert flips == 2, "the setpoint flips sign every LONG_TRACE_STEP_S"
