"""tools/bench.py's report: the field recorder's rows (armed vs idle, armed vs a demo cycle)."""

from __future__ import annotations

import importlib.util
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
