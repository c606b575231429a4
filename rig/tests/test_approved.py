"""Approved traces (hilrig.pytest_plugin.approved): a run's TPDO rows, EMCYs and SDO aborts
written exactly and read back, a change named by its first cycle, field and both values, and
the plugin's three modes in a project of its own (`pytester`) on a real `History` the scenario
fills, as a lockstep driver does. The scenarios on a bus check theirs in tests/."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from boardproto.cia301 import FunctionCode, SdoAbortCode, cob_id
from hilrig.engine.history import History
from hilrig.pytest_plugin.approved import ApprovedRecorder, compare_traces, from_json, to_json
from hilrig.table import EmcyCode
from hilrig.wire.node import EmcyRecord
from hilrig.wire.transport import PdoDirection, PdoLayout

NODE = 1
DUTY = PdoLayout(
    PdoDirection.TPDO, 1, cob_id(FunctionCode.TPDO1, NODE), True, 1, ("motor_duty", "mode"), ("f", "B")
)
STATUS = PdoLayout(PdoDirection.TPDO, 2, cob_id(FunctionCode.TPDO2, NODE), True, 1, ("fault_flags",), ("H",))
SETPOINT = PdoLayout(
    PdoDirection.RPDO, 1, cob_id(FunctionCode.RPDO1, NODE), True, 255, ("velocity_setpoint",), ("f",)
)
OVERRUN = EmcyCode.RECEIVE_OVERRUN
ABORT = SdoAbortCode.VALUE_RANGE_EXCEEDED


def recorded(
    cycles: int = 300, kick_at: int | None = None, every_other_status: bool = False
) -> ApprovedRecorder:
    """A run of `cycles`: a noisy duty, a mode that steps at cycle 100, status every cycle (or
    every other), one EMCY and one SDO abort; `kick_at`: the duty a little off from there on."""
    history = History(1000)
    recorder = ApprovedRecorder("main")
    recorder.on_history(history)
    noise = np.random.default_rng(5).normal(0.0, 0.1, cycles).astype(np.float32)
    for cycle in range(cycles):
        duty = float(noise[cycle]) + (1e-3 if kick_at is not None and cycle >= kick_at else 0.0)
        received = [(DUTY, (duty, 1 if cycle < 100 else 2))]
        if not every_other_status or cycle % 2 == 0:
            received.append((STATUS, (0 if cycle < 200 else 4,)))
        history.record_rows(cycle, received, [(SETPOINT, (3.0,))])
        history.record_truth(None)
    recorder.on_emcy(EmcyRecord(OVERRUN, 0x11, b"\x01\x00\x00\x00\x00", 200, 0.2))
    recorder.on_sdo_abort("write", ABORT, cycle=120, t=0.12)
    return recorder


def test_a_run_reads_back_exactly_and_agrees_with_itself() -> None:
    run = recorded().run()
    text = to_json("tests/test_x.py::test_y", [run])
    again = from_json(text)[0]
    assert [p.key for p in again.pdos] == ["TPDO 0x181 (motor_duty, mode)", "TPDO 0x281 (fault_flags)"]
    for before, after in zip(run.pdos, again.pdos, strict=True):
        assert np.array_equal(before.cycles, after.cycles)
        assert before.rows.tobytes() == after.rows.tobytes()
    assert again.emcy == [(200, OVERRUN, 0x11, "0100000000")] and again.aborts == [(120, ABORT)]
    assert compare_traces([again], [run]) == []
    assert "velocity_setpoint" not in text, "what the rig sent is not the node's behaviour"
    assert len(json.loads(text)["runs"][0]["data"]) < 300 * 4 * 2, "a noisy float costs a few bytes a cycle"


def test_an_emcy_after_the_node_left_lockstep_is_not_recorded() -> None:
    # Once the node is no longer operational the rig's SYNCs go unanswered: when its EMCYs come
    # is the host's timing, so the approved trace keeps only those of the lockstep.
    operational = {"now": True}
    recorder = ApprovedRecorder("main", lambda: operational["now"])
    recorder.on_history(History(1000))
    recorder.on_emcy(EmcyRecord(OVERRUN, 0x11, b"\x01\x00\x00\x00\x00", 200, 0.2))
    operational["now"] = False
    recorder.on_emcy(EmcyRecord(EmcyCode.STALE_SENSOR, 0x01, b"\x00\x20\x00\x00\x00", 240, 0.24))
    assert recorder.run().emcy == [(200, OVERRUN, 0x11, "0100000000")]


def test_a_change_is_named_by_its_first_cycle_field_and_values() -> None:
    base = recorded().run()
    lines = compare_traces([base], [recorded(kick_at=157).run()])
    assert lines[0] == "compared 4 series over cycles 0..299", lines
    assert lines[1].startswith("first divergence: motor_duty at cycle 157 (t = 0.157 s): "), lines
    kicked = recorded(kick_at=157).run()
    kicked.emcy.append((250, EmcyCode.HEARTBEAT_ERROR, 0x11, "00"))
    assert compare_traces([base], [kicked], every=True)[1:] == [
        "  motor_duty at cycle 157 (t = 0.157 s): -0.0276761 vs -0.0266761",
        "  emcy at cycle 250 (t = 0.250 s): '(none)' vs 'cycle 250 0x8130 17 00'",
    ]
    later = recorded(cycles=301).run()
    assert compare_traces([base], [later]) == [
        "compared 4 series over cycles 0..299 (base 0..299, cand 0..300)",
        "first divergence: TPDO 0x181 at cycle 300 (t = 0.300 s): 'not sent' vs 'sent'",
        "  then TPDO 0x281 at cycle 300 (t = 0.300 s): 'not sent' vs 'sent'",
    ]


def test_a_tpdo_missing_in_a_cycle_and_a_lost_emcy_are_divergences() -> None:
    base = recorded().run()
    sparse = recorded(every_other_status=True).run()
    assert compare_traces([base], [sparse])[1] == (
        "first divergence: TPDO 0x281 at cycle 1 (t = 0.001 s): 'sent' vs 'not sent'"
    )
    quiet = recorded()
    quiet.emcy.clear()
    assert compare_traces([base], [quiet.run()])[1] == (
        "first divergence: emcy at cycle 200 (t = 0.200 s): 'cycle 200 0x8110 17 0100000000' vs '(none)'"
    )


SCENARIO = """
import os
import pytest
from hilrig.pytest_plugin import approved
import test_approved as runs

@pytest.fixture
def fake_rig(request):
    class Watched:
        def add_observer(self, observer):
            kick = os.environ.get("KICK")
            source = runs.recorded(kick_at=int(kick) if kick else None)
            observer.on_history(source.history)
            for entry in source.emcy:
                observer.emcy.append(entry)
    approved.watch(request.node, Watched(), "main")

def test_scenario(fake_rig):
    pass

@pytest.mark.no_approved_trace("a wall clock decides it")
def test_exempt(fake_rig):
    pass
"""


def test_the_plugin_writes_checks_and_updates(
    pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch
) -> None:
    pytester.makepyfile(test_scenario=SCENARIO)
    pytester.syspathinsert(str(Path(__file__).parent))
    monkeypatch.delenv("CI", raising=False)
    monkeypatch.delenv("KICK", raising=False)
    approved = pytester.path / "approved" / "test_scenario.test_scenario.json"

    monkeypatch.setenv("CI", "true")
    missing = pytester.runpytest("-p", "no:cacheprovider")
    missing.assert_outcomes(passed=1, failed=1)
    missing.stdout.fnmatch_lines(
        ["*no approved trace *test_scenario.test_scenario.json: run `pytest --hil-approved=update*"]
    )
    monkeypatch.delenv("CI")

    pytester.runpytest("-p", "no:cacheprovider").assert_outcomes(passed=2)
    assert approved.is_file() and not (pytester.path / "approved" / "test_scenario.test_exempt.json").exists()
    written = approved.read_text()

    monkeypatch.setenv("KICK", "42")
    changed = pytester.runpytest("-p", "no:cacheprovider")
    changed.assert_outcomes(passed=1, failed=1)
    changed.stdout.fnmatch_lines(["*first divergence: motor_duty at cycle 42 (t = 0.042 s): *"])
    pytester.runpytest("-p", "no:cacheprovider", "--hil-approved=off").assert_outcomes(passed=2)
    assert approved.read_text() == written

    updated = pytester.runpytest("-p", "no:cacheprovider", "--hil-approved=update")
    updated.assert_outcomes(passed=2)
    updated.stdout.fnmatch_lines(["*approved traces written*", "*changed *test_scenario.test_scenario.json*"])
    assert approved.read_text() != written
