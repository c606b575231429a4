"""The bench's baseline (`hilrig.apps.bench.baseline`): the engine of a baseline commit beside
the checkout's. A commit that cannot be measured is a row 'not measured' with the reason; the
ratio rows are computed and judged against the goal; the baseline's tree is exported once,
reused, replaced and removed cleanly; the `baseline` subcommand writes its rows whatever fails;
and the default baseline's own probe runs from its exported tree, importing nothing of the
checkout's."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Any

import pytest

from hilrig.apps.bench import baseline as bench_baseline
from hilrig.apps.bench import common as bench_common
from hilrig.apps.bench import main as bench
from hilrig.apps.bench import native as bench_native
from hilrig.apps.bench import report as bench_report

MISSING_COMMIT = "0123456789abcdef0123456789abcdef01234567"


def _rows(probe: dict[str, float] | None, baseline: dict[str, Any] | None, not_measured: dict[str, str]):
    rows = bench_report.ReportRows()
    bench_baseline.baseline_rows(rows, probe, baseline, not_measured)
    return rows


def _never_counted(mode: str, tree: Path) -> float:
    raise AssertionError(f"counted {mode} of {tree} without a tree")


# --- Not measured, with the reason ---------------------------------------------------------------
def test_a_missing_commit_is_a_row_not_measured_with_the_reason(tmp_path: Path) -> None:
    not_measured = bench_common.NotMeasured()
    record = bench_baseline.measure_baseline(tmp_path, MISSING_COMMIT, not_measured, _never_counted)
    assert record == {"asked": MISSING_COMMIT}
    assert set(not_measured) == {"baseline"}
    assert "no such commit" in not_measured["baseline"]
    assert not (tmp_path / bench_baseline.BASELINE_FOLDER).exists()  # nothing exported
    rows = _rows({"rig": 100.0, "engine": 50.0}, record, not_measured)
    versus = f"this checkout vs baseline {MISSING_COMMIT[:10]}"
    assert [r["measure"] for r in rows] == [
        f"instructions/cycle (main thread): Rig lockstep cycle, {versus}",
        f"instructions/cycle (main thread): engine's exchange alone, {versus}",
    ]
    for row in rows:
        assert (row["ours"], row["ratio"], row["goal_met"]) == ("not measured", None, None)
        assert row["baseline"].startswith(f"baseline {MISSING_COMMIT!r}: no such commit in ")
        assert row["data"]["error"] == not_measured["baseline"]


def test_outside_a_repository_or_without_git_the_reason_says_which(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    with pytest.raises(bench_common.ProbeError, match="is not a git repository"):
        bench_baseline.resolve_commit("HEAD", repo=tmp_path)
    monkeypatch.setattr(bench_baseline.shutil, "which", lambda name: None)
    with pytest.raises(bench_common.ProbeError, match=r"git is not installed"):
        bench_baseline.resolve_commit("HEAD")


def test_a_figure_missing_on_either_side_is_not_measured_with_that_sides_reason() -> None:
    baseline = {"asked": "dbf1cf7", "commit": "dbf1cf7" + "0" * 33, "engine": 50.0}
    not_measured = {"baseline rig": "valgrind: timed out", "rig_probe engine": "rig_probe.py: exit status 1"}
    rig, engine = _rows({"rig": 100.0}, baseline, not_measured)
    assert (rig["ours"], rig["baseline"]) == ("not measured", "valgrind: timed out")
    assert (engine["ours"], engine["baseline"]) == ("not measured", "rig_probe.py: exit status 1")


# --- The ratio, judged ---------------------------------------------------------------------------
def test_the_ratio_rows_are_new_over_old_and_judged_within_ten_percent() -> None:
    sha = "dbf1cf78d9d82ecd3e6ecd74856c989a8b7d95a5"
    baseline = {"asked": "dbf1cf7", "commit": sha, "rig": 100_000.0, "engine": 50_000.0}
    rig, engine = _rows({"rig": 105_000.4, "engine": 60_000.0}, baseline, {})
    assert rig["measure"].endswith("Rig lockstep cycle, this checkout vs baseline dbf1cf78d9")
    assert (rig["ours"], rig["baseline"], rig["goal"]) == ("105000", "100000", "within 10% (<= 1.1)")
    assert rig["ratio"] == pytest.approx(1.05, abs=1e-5)
    assert rig["goal_met"] is True
    assert rig["data"] == baseline  # the commit asked for and its hash, in the report's data
    assert engine["ratio"] == pytest.approx(1.2)
    assert engine["goal_met"] is False
    faster, at_goal = _rows({"rig": 80_000.0, "engine": 55_000.0}, baseline, {})
    assert faster["goal_met"] is True  # a faster engine meets it
    assert at_goal["ratio"] == pytest.approx(1.1) and at_goal["goal_met"] is True


def test_the_counts_of_a_prepared_tree_are_recorded_with_its_commit(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    tree = tmp_path / "baseline" / ("ab" * 20)
    monkeypatch.setattr(bench_baseline, "prepare_baseline", lambda out, commit: tree)
    counted: list[tuple[str, Path]] = []

    def per_cycle(mode: str, root: Path) -> float:
        counted.append((mode, root))
        return {"rig": 1000.0, "engine": 400.0}[mode]

    not_measured = bench_common.NotMeasured()
    record = bench_baseline.measure_baseline(tmp_path, "v1", not_measured, per_cycle)
    assert record == {"asked": "v1", "commit": "ab" * 20, "rig": 1000.0, "engine": 400.0}
    assert counted == [("rig", tree), ("engine", tree)]
    assert not not_measured


# --- The exported tree: once, reused, replaced, removed ------------------------------------------
def _git(repo: Path, *args: str) -> str:
    identity = ["-c", "user.name=bench", "-c", "user.email=bench@example.invalid"]
    command = ["git", "-C", str(repo), *identity, *args]
    return subprocess.run(command, capture_output=True, text=True, check=True).stdout.strip()


def _repo_of_three_commits(path: Path) -> tuple[str, str, str]:
    """A repository of three commits: the first two with a tools/rig_probe.py, the third without."""
    path.mkdir()
    _git(path, "init", "-q")
    commits = []
    trees = ({"tools/rig_probe.py": "one"}, {"tools/rig_probe.py": "two"}, {"README": "x"})
    for n, files in enumerate(trees):
        for name, text in files.items():
            (path / name).parent.mkdir(parents=True, exist_ok=True)
            (path / name).write_text(text)
        if n == 2:
            _git(path, "rm", "-q", "tools/rig_probe.py")
        _git(path, "add", "-A")
        _git(path, "commit", "-q", "-m", f"commit {n}")
        commits.append(_git(path, "rev-parse", "HEAD"))
    return commits[0], commits[1], commits[2]


def test_the_tree_is_exported_once_reused_replaced_and_removed(tmp_path: Path) -> None:
    repo, out = tmp_path / "repo", tmp_path / "bench"
    first, second, without_probe = _repo_of_three_commits(repo)
    made: list[str] = []

    def make_runnable(tree: Path) -> None:
        made.append((tree / "tools" / "rig_probe.py").read_text())

    tree = bench_baseline.export_tree(first, out, make_runnable, repo=repo)
    assert tree == out / "baseline" / first
    assert (tree / "tools" / "rig_probe.py").read_text() == "one"
    assert bench_baseline.export_tree(first, out, make_runnable, repo=repo) == tree
    assert made == ["one"]  # reused: not exported or built again
    other = bench_baseline.export_tree(second, out, make_runnable, repo=repo)
    assert made == ["one", "two"]
    assert sorted(p.name for p in (out / "baseline").iterdir()) == [second]  # the first one removed

    def failing_build(tree: Path) -> None:
        raise bench_common.ProbeError("setup.py: exit status 1")

    (other / ".bench-baseline.json").unlink()  # as if that export had stopped half-way
    with pytest.raises(bench_common.ProbeError, match=r"setup\.py"):
        bench_baseline.export_tree(second, out, failing_build, repo=repo)
    assert list((out / "baseline").iterdir()) == []  # the half-done one and the failed one gone
    with pytest.raises(bench_common.ProbeError, match=r"no tools/rig_probe\.py"):
        bench_baseline.export_tree(without_probe, out, make_runnable, repo=repo)
    assert list((out / "baseline").iterdir()) == []
    bench_baseline.export_tree(first, out, make_runnable, repo=repo)
    bench_baseline.remove_baseline(out)
    assert not (out / "baseline").exists()


# --- The default baseline's own probe, from its exported tree ------------------------------------
@pytest.mark.timeout(300)
def test_the_default_baselines_probe_runs_from_its_own_tree(tmp_path: Path) -> None:
    """Exported, built (its C extensions, its EDS) and checked natively: its probe ran a few
    cycles of each mode importing hilrig and boardproto from that tree only."""
    try:
        sha = bench_baseline.resolve_commit(bench_baseline.DEFAULT_BASELINE)
    except bench_common.ProbeError as error:  # a shallow clone: the comparison is not measured
        pytest.skip(str(error))
    tree = bench_baseline.prepare_baseline(tmp_path, bench_baseline.DEFAULT_BASELINE)
    assert tree == tmp_path / "baseline" / sha
    assert list((tree / "rig").rglob("_wire*.so")), "its own raw-socket exchange, built in place"
    assert (tree / "build" / "protocol" / "board.eds").is_file()


def test_a_probe_that_imports_the_checkouts_rig_is_refused(tmp_path: Path) -> None:
    """A tree whose probe does not put its own rig/ first gets the venv's editable hilrig, the
    checkout's: its figures would be the checkout's, so the check refuses it, naming the module."""
    (tmp_path / "tools").mkdir()
    (tmp_path / "tools" / "rig_probe.py").write_text("import hilrig\n")
    with pytest.raises(bench_common.ProbeError, match="imported modules from outside its tree: hilrig from"):
        bench_baseline.check_probe(tmp_path)
    (tmp_path / "tools" / "rig_probe.py").write_text("import sys\nsys.exit(0)\n")
    bench_baseline.check_probe(tmp_path)


# --- In the report, and the `baseline` subcommand ------------------------------------------------
def test_the_printed_table_says_met_or_missed() -> None:
    baseline = {"asked": "dbf1cf7", "commit": "dbf1cf7" + "0" * 33, "rig": 100_000.0, "engine": 50_000.0}
    one_met_one_missed = _rows({"rig": 100_000.0, "engine": 60_000.0}, baseline, {})
    rig, engine = bench_report.format_table(one_met_one_missed)[2:]
    assert rig.endswith("100000    1      within 10% (<= 1.1): met")
    assert engine.endswith("50000     1.2    within 10% (<= 1.1): MISSED")


def test_a_native_json_from_before_the_comparison_says_so_in_the_report() -> None:
    native = {"date": "today", "machine": {}, "board_bench_ns": {}, "callgrind": None}
    report = bench_report.build_report(native, {}, "native", {"error": "none"})
    rows = [r for r in report["rows"] if "this checkout vs baseline" in r["measure"]]
    assert [(r["ours"], r["baseline"]) for r in rows] == [("not measured", bench_baseline.NO_BASELINE)] * 2
    assert rows[0]["measure"].endswith(f"vs baseline {bench_baseline.DEFAULT_BASELINE}")


def test_the_baseline_step_writes_its_rows_when_the_commit_is_missing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(bench_native, "prepare_checkout", lambda: None)
    monkeypatch.setattr(
        bench_native, "rig_probe_instructions", lambda mode, cycles, root, **_: 10_000 + cycles * 900
    )
    assert bench.main(["baseline", "--out", str(tmp_path), "--baseline", MISSING_COMMIT]) == 1
    printed = capsys.readouterr().out
    assert "Rig lockstep cycle, this checkout vs baseline" in printed and "not measured" in printed
    result = json.loads((tmp_path / "baseline.json").read_text())
    assert result["rig_probe"] == {"rig": 900.0, "engine": 900.0}
    assert result["baseline"] == {"asked": MISSING_COMMIT}
    assert [row["ours"] for row in result["rows"]] == ["not measured"] * 2
    assert not (tmp_path / "native.json").exists()


def test_the_baseline_step_compares_both_trees_counted_alike(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    old_tree = tmp_path / "baseline" / ("cd" * 20)
    monkeypatch.setattr(bench_native, "prepare_checkout", lambda: None)
    monkeypatch.setattr(bench_baseline, "prepare_baseline", lambda out, commit: old_tree)

    def instructions(mode: str, cycles: int, root: Path, **_: Any) -> int:
        per_cycle = {"rig": 1000, "engine": 500}[mode] * (1.0 if root == old_tree else 1.04)
        return round(1_000_000 + cycles * per_cycle)

    monkeypatch.setattr(bench_native, "rig_probe_instructions", instructions)
    assert bench.main(["baseline", "--out", str(tmp_path)]) == 0
    rows = json.loads((tmp_path / "baseline.json").read_text())["rows"]
    assert [(r["ours"], r["baseline"], r["goal_met"]) for r in rows] == [
        ("1040", "1000", True),
        ("520", "500", True),
    ]
    assert [r["ratio"] for r in rows] == pytest.approx([1.04, 1.04])
    assert bench.main(["baseline", "--out", str(tmp_path), "--remove"]) == 0
