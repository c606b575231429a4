"""`hilrig diff`: two traces compared cycle by cycle (`hilrig.observe.diff`), on traces a Rig wrote
against the in-process fake node, and on hand-made ones for the rules (holding, tolerance, NaN,
events, runs of different length)."""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import pytest
from fake_rig import traced_fake_rig

from hilrig.cli import main as hilrig
from hilrig.observe.dashboard_check import fitting_dashboards, trace_gaps
from hilrig.observe.diff import Tolerance, compare
from hilrig.observe.paths import DIFF_BASE_ROOT, DIFF_CAND_ROOT, DIFF_EVENTS_PATH, DIFF_ROOT
from hilrig.observe.reader import Trace
from hilrig.observe.sinks import TraceSink
from hilrig.observe.tracer import Tracer
from hilrig.table import RigTable

KP_WRITTEN_AT = 12
"""The cycle a run writes velocity_kp over SDO."""
WALL_CLOCK = ["--ignore", "/events/nmt"]
"""The fake node is canopen's LocalNode: its heartbeat (the rig's NMT events) keeps wall time."""


def traced_run(path: Path, velocity_kp: float, cycles: int = 30) -> Path:
    """A traced Rig run against the fake node: a velocity step, velocity_kp written at cycle 12."""
    table = RigTable.load()
    tracer = Tracer(TraceSink.rrd(path), table, batch_cycles=10, background=False, blueprint="overview")
    with traced_fake_rig(tracer, table) as rig:
        rig.set("velocity_setpoint", 2.0)
        rig.run(cycles=KP_WRITTEN_AT)
        rig.set("velocity_kp", velocity_kp)
        rig.run(cycles=cycles - KP_WRITTEN_AT)
    return path


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("diff")
    return {
        "base": traced_run(root / "base.rrd", 0.25),
        "again": traced_run(root / "again.rrd", 0.25),
        "kp": traced_run(root / "kp.rrd", 0.3),
        "short": traced_run(root / "short.rrd", 0.25, cycles=20),
    }


def test_two_runs_alike_have_no_difference(runs: dict[str, Path], tmp_path: Path, capsys) -> None:
    out_path = str(tmp_path / "d.rrd")
    assert hilrig(["diff", str(runs["base"]), str(runs["again"]), "-o", out_path, *WALL_CLOCK]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[:2] == [out[0], "no difference"] and out[0].startswith("compared "), out


def test_another_gain_is_named_at_the_cycle_it_was_written(
    runs: dict[str, Path], tmp_path: Path, capsys
) -> None:
    out_path = tmp_path / "d.rrd"
    assert hilrig(["diff", str(runs["base"]), str(runs["kp"]), "-o", str(out_path), *WALL_CLOCK]) == 1
    lines = capsys.readouterr().out.splitlines()
    assert lines[1] == f"first divergence: velocity_kp at cycle {KP_WRITTEN_AT} (t = 0.012 s): 0.25 vs 0.3"
    comparison = Trace.read(out_path)
    # Both runs and the difference on one timeline; the divergences as text at their cycle.
    velocity_kp = "/fields/parameters/velocity_kp"
    assert comparison.scalars[DIFF_BASE_ROOT + velocity_kp] == [0.25]
    assert comparison.scalars[DIFF_CAND_ROOT + velocity_kp] == [pytest.approx(0.3)]
    assert comparison.scalars[DIFF_ROOT + velocity_kp] == [pytest.approx(0.05)]
    first_text, level = comparison.texts[DIFF_EVENTS_PATH][0]
    assert first_text.startswith("first divergence: velocity_kp") and level == "ERROR"
    assert comparison.cycles[DIFF_EVENTS_PATH][0] == KP_WRITTEN_AT
    # It opens with the diff dashboard, and every series that dashboard names has data.
    assert comparison.blueprints == 1
    dashboards = fitting_dashboards(comparison)
    assert list(dashboards) == ["diff"]
    assert trace_gaps(comparison, dashboards) == []


def test_a_shorter_run_is_compared_over_the_cycles_both_reached(runs: dict[str, Path]) -> None:
    result = compare(Trace.read(runs["base"]), Trace.read(runs["short"]), ignore=["/events/nmt"])
    assert result.base_cycles == (0, 29) and result.cand_cycles == (0, 19)
    assert result.first is None
    assert "over cycles 0..19 (base 0..29, cand 0..19)" in result.summary()[0]


def test_the_default_out_is_beside_the_candidate(runs: dict[str, Path], tmp_path: Path) -> None:
    cand = tmp_path / "cand.rrd"
    cand.write_bytes(runs["kp"].read_bytes())
    assert hilrig(["diff", str(runs["base"]), str(cand)]) == 1
    assert (tmp_path / "diff.rrd").is_file()


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (["nowhere.rrd", "{base}"], "trace nowhere.rrd does not exist"),
        (["{text}", "{base}"], "is not a Rerun recording"),
        (["{base}", "{base}", "--atol", "-1"], "expected a finite number >= 0"),
        (["{base}", "{base}", "-o", "{base}"], "would overwrite a recording being compared"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(
    runs: dict[str, Path], tmp_path: Path, capsys, arguments: list[str], message: str
) -> None:
    text = tmp_path / "notes.rrd"
    text.write_text("not a recording\n")
    argv = [a.format(base=runs["base"], text=text) for a in arguments]
    assert hilrig(["diff", *argv]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if not line.startswith("diff: reading")]
    assert len(err) == 1 and message in err[0], err


def test_view_without_a_display_says_to_add_web(
    runs: dict[str, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    for name in ("DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET"):
        monkeypatch.delenv(name, raising=False)
    argv = ["diff", str(runs["base"]), str(runs["kp"]), "-o", str(tmp_path / "d.rrd"), "--view", *WALL_CLOCK]
    assert hilrig(argv) == 2
    assert "add --web" in capsys.readouterr().err


def hand_made(
    series: dict[str, tuple[list[int], list[float]]], texts: dict[str, list[tuple[int, str]]] | None = None
) -> Trace:
    trace = Trace()
    for path, (cycles, values) in series.items():
        trace.cycles[path] = list(cycles)
        trace.times[path] = [c * 0.001 for c in cycles]
        trace.scalars[path] = list(values)
    for path, entries in (texts or {}).items():
        trace.cycles[path] = [c for c, _ in entries]
        trace.times[path] = [c * 0.001 for c, _ in entries]
        trace.texts[path] = [(t, "INFO") for _, t in entries]
    trace.rows = defaultdict(int, {p: len(c) for p, c in trace.cycles.items()})
    return trace


def test_a_step_series_is_held_between_its_rows() -> None:
    # base logs its changes only; cand logs every cycle with the same held values: no difference.
    base = hand_made({"/x": ([0, 5], [1.0, 2.0])})
    cand = hand_made({"/x": ([0, 1, 2, 3, 4, 5, 6], [1.0, 1.0, 1.0, 1.0, 1.0, 2.0, 2.0])})
    assert compare(base, cand).first is None
    moved = hand_made({"/x": ([0, 4], [1.0, 2.0])})
    first = compare(base, moved).first
    assert first is not None and (first.cycle, first.base, first.cand) == (4, 1.0, 2.0)


def test_tolerances_and_nan() -> None:
    base = hand_made({"/x": ([0, 1, 2], [1.0, 1.0, float("nan")])})
    close = hand_made({"/x": ([0, 1, 2], [1.0, 1.0 + 5e-7, float("nan")])})
    assert compare(base, close).first is None  # within rtol 1e-6, NaN on both sides is equal
    assert compare(base, close, Tolerance(atol=0.0, rtol=0.0)).first.cycle == 1  # type: ignore[union-attr]
    one_nan = hand_made({"/x": ([0, 1, 2], [1.0, 1.0, 3.0])})
    assert compare(base, one_nan).first.cycle == 2  # type: ignore[union-attr]


def test_events_part_at_their_first_other_entry_and_causes_come_first_at_one_cycle() -> None:
    x, sent = "/fields/sensors/x", "/fields/parameters/kp"
    base = hand_made(
        {x: ([0, 3], [0.0, 0.0]), sent: ([3], [1.0])}, {"/events/emcy": [(1, "EMCY a"), (3, "EMCY b")]}
    )
    cand = hand_made(
        {x: ([0, 3], [0.0, 1.0]), sent: ([3], [2.0])}, {"/events/emcy": [(1, "EMCY a"), (3, "EMCY c")]}
    )
    result = compare(base, cand)
    # What the rig sent, then what the node answered, then the events.
    assert [(d.path, d.cycle) for d in result.divergences] == [(sent, 3), (x, 3), ("/events/emcy", 3)]
    assert (result.divergences[2].base, result.divergences[2].cand) == ("EMCY b", "EMCY c")
    fewer = hand_made({x: ([0, 3], [0.0, 0.0]), sent: ([3], [1.0])}, {"/events/emcy": [(1, "EMCY a")]})
    missing = compare(base, fewer).first
    assert missing is not None and (missing.cycle, missing.cand) == (3, "(no entry)")


def test_a_series_in_one_run_only_is_a_difference() -> None:
    base = hand_made({"/x": ([0], [0.0]), "/y": ([0], [0.0])})
    cand = hand_made({"/x": ([0], [0.0])})
    result = compare(base, cand)
    assert not result.same and result.only_base == ["/y"]
    assert result.summary()[1:] == ["no difference in the series both runs hold", "only in base: /y"]
