"""`make mutate` (tools/mutate.py): the firmware's mutants, their seeded sample and its shards,
and a whole run of the build and unit-test layers on a tiny CMake tree (mutate_tiny: one product
file, two unit tests), down to the report in Stryker's schema and the merge of shards."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

TOOLS = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(TOOLS))
import mutate  # noqa: E402
import mutate_coverage as coverage  # noqa: E402
import mutate_kept  # noqa: E402
import mutate_sampling as sampling  # noqa: E402
import mutate_scenarios  # noqa: E402
import mutation_report as report  # noqa: E402

TINY = Path(__file__).resolve().parent / "mutate_tiny"
STRYKER_STATUSES = {
    "Killed",
    "Survived",
    "NoCoverage",
    "CompileError",
    "RuntimeError",
    "Timeout",
    "Ignored",
    "Pending",
}


def tiny_mutant(line_text: str, replacement_text: str) -> mutate.Mutant:
    for mutant in mutate.all_mutants(TINY, mutate.product_files(TINY)):
        if (
            " ".join(mutant.original.split()) == line_text
            and " ".join(mutant.replacement.split()) == replacement_text
        ):
            return mutant
    raise AssertionError(f"no mutant {line_text!r} -> {replacement_text!r}")


def test_the_firmware_s_product_code_is_mutated_not_its_tests() -> None:
    files = mutate.product_files(mutate.REPO)
    assert "firmware/canopen/Node.cpp" in files and "firmware/joint/modules/ThermalProtection.cpp" in files
    for path in files:
        assert not path.endswith("Test.cpp"), path
        assert not path.startswith(
            ("firmware/bench/", "firmware/canopen/fuzz/", "firmware/joint/testing/")
        ), path


SOME_FILES = (
    "firmware/canopen/Pdo.cpp",
    "firmware/core/MessageBoard.hpp",
    "firmware/joint/modules/ThermalProtection.cpp",
    "firmware/canopen/TimeLeft.hpp",
)


def test_the_sample_is_stratified_seeded_and_its_shards_partition_it() -> None:
    files = [f for f in SOME_FILES if (mutate.REPO / f).exists()]
    everything = mutate.all_mutants(mutate.REPO, files)
    assert len({m.id for m in everything}) == len(everything), "mutant ids must be unique"
    plan = sampling.plan(everything, 12, seed=5)
    assert plan.count == 12 and set(plan.targets) == set(files), "every file gets its share"
    assert [m.id for m in sampling.first_choices(plan)] == [
        m.id for m in sampling.first_choices(sampling.plan(everything, 12, seed=5))
    ]
    assert sampling.first_choices(plan) != sampling.first_choices(sampling.plan(everything, 12, seed=6))
    for count in (2, 3, 5):
        shards = [sampling.plan(everything, 12, 5, (k, count)) for k in range(1, count + 1)]
        assert sum(s.count for s in shards) == 12
        for path in files:
            assert sum(s.targets.get(path, 0) for s in shards) == plan.targets[path]
            parts = [m.id for s in shards for m in s.candidates.get(path, [])]
            assert len(parts) == len(set(parts)), "no candidate in two shards"


def test_shares_are_proportional_with_one_for_every_file() -> None:
    assert sampling.shares({"a": 100, "b": 10, "c": 1}, 12) == {"a": 9, "b": 2, "c": 1}
    assert sampling.shares({"a": 100, "b": 10, "c": 1}, 2) == {"a": 2}
    assert sum(sampling.shares({str(n): n + 1 for n in range(40)}, 200).values()) == 200


def test_a_mutant_that_does_not_count_is_replaced_by_its_file_s_next() -> None:
    make = lambda path, n: mutate.Mutant(f"{path}-{n}", path, n, "x\n", "y\n", "r")  # noqa: E731
    mutants = [make("a.cpp", n) for n in range(1, 6)] + [make("b.cpp", n) for n in range(1, 6)]
    plan = sampling.plan(mutants, 4, seed=1)
    broken = {m.id for m in plan.candidates["a.cpp"][:2]}  # its first two do not compile
    taken = list(sampling.take(plan, lambda m: m.id not in broken))
    assert sum(m.path == "a.cpp" for m in taken) == 4 and sum(m.path == "b.cpp" for m in taken) == 2
    assert len([m for m in taken if m.id not in broken]) == 4, "MUTANTS counts mutants, not draws"


def test_the_interval_is_wilson_s() -> None:
    low, high = report.wilson(14, 15)
    assert round(low, 1) == 70.2 and round(high, 1) == 98.8
    assert report.wilson(0, 10)[0] == 0.0 and round(report.wilson(10, 10)[1], 6) == 100.0
    assert report.wilson(0, 0) is None
    assert str(report.Score(190, 200)) == "190/200 = 95.0 % (95 % CI 91.0-97.3 %)"


def test_a_mutant_runs_only_the_tests_that_execute_its_line() -> None:
    record = coverage.Coverage.build(
        "digest",
        {
            "scenario:tests/a.py::one": {"firmware/X.cpp": {10: True, 11: False}},
            "scenario:tests/b.py::two": {"firmware/X.cpp": {10: True, 11: False, 12: True}},
            "scenario:tests/c.py::killed": {},
            "unit:x_test": {"firmware/X.cpp": {10: False, 12: True}},
        },
    )
    record = coverage.Coverage.from_json(json.loads(json.dumps(record.to_json())))
    both = ["tests/a.py::one", "tests/b.py::two", "tests/c.py::killed"]
    assert record.covering("firmware/X.cpp", 10, coverage.SCENARIO) == both
    assert record.covering("firmware/X.cpp", 11, coverage.SCENARIO) == ["tests/c.py::killed"], (
        "none executes it; one left no counters and may"
    )
    assert record.covering("firmware/X.cpp", 13, coverage.SCENARIO) is None, "not instrumented: all"
    assert record.covering("firmware/X.cpp", 10, coverage.UNIT) == []
    assert record.covering("firmware/X.cpp", 12, coverage.UNIT) == ["x_test"]
    merged = coverage.merge([record])
    assert merged.covering("firmware/X.cpp", 12, coverage.SCENARIO) == [
        "tests/b.py::two",
        "tests/c.py::killed",
    ]


def test_a_header_line_run_only_by_a_unity_test_file_is_recorded(tmp_path: Path) -> None:
    # The project's build maps the source tree to "." (-ffile-prefix-map) and a unity test file
    # includes its tests by absolute path: gcov then names their headers relative to the
    # source tree, not the build tree. A line lost so runs no unit test against its mutants.
    src, build = tmp_path / "src", tmp_path / "build"
    (src / "fw").mkdir(parents=True)
    build.mkdir()
    (src / "fw" / "Gate.hpp").write_text("inline bool open(int x) {\n  return x > 2;\n}\n")
    test = '#include "fw/Gate.hpp"\nint main() { return open(3) ? 0 : 1; }\n'
    (src / "fw" / "GateTest.cpp").write_text(test)
    (build / "unity_0_cxx.cxx").write_text(f'#include "{src}/fw/GateTest.cpp"\n')
    subprocess.run(
        ["g++", "--coverage", f"-I{src}", f"-ffile-prefix-map={src}=.", "-c", "unity_0_cxx.cxx"],
        cwd=build,
        check=True,
    )
    subprocess.run(["g++", "--coverage", "unity_0_cxx.o", "-o", "gate_test"], cwd=build, check=True)
    counters = tmp_path / "counters"
    subprocess.run([build / "gate_test"], env={**os.environ, "GCOV_PREFIX": str(counters)}, check=True)
    lines = coverage.executed_lines(counters, build, src)
    assert lines["fw/Gate.hpp"][2] is True, lines


def test_a_mutant_applies_to_its_line_only() -> None:
    mutant = tiny_mutant("if (duty > limit) return limit;", "if (duty < limit) return limit;")
    text = (TINY / mutant.path).read_text()
    changed = mutant.apply(text)
    assert changed.count("\n") == text.count("\n")
    assert [a != b for a, b in zip(text.splitlines(), changed.splitlines(), strict=True)].count(True) == 1
    with pytest.raises(ValueError, match="no longer"):
        mutant.apply(text.replace("duty > limit", "duty >= limit"))


def test_a_run_on_a_tiny_tree_builds_tests_and_reports(tmp_path: Path) -> None:
    killed = tiny_mutant("if (duty > limit) return limit;", "if (duty < limit) return limit;")
    survivor = tiny_mutant("return value * 3;", "return value * 1;")
    broken = tiny_mutant("factor = factor + value;", "value = factor + value;")  # a const assigned
    out = tmp_path / "out"
    argv = [
        "run",
        "--source",
        str(TINY),
        "--sources",
        "CMakeLists.txt",
        "firmware",
        "--cmake-arg=-DCMAKE_BUILD_TYPE=Debug",
    ]
    kept_file = tmp_path / "judged.json"
    argv += ["--no-scenarios", "--jobs", "2", "--kept", str(kept_file), "--out", str(out)]
    for mutant in (killed, survivor, broken):
        argv += ["--mutant", mutant.id]
    assert mutate.main(argv) == 0
    assert (TINY / killed.path).read_text().count("duty > limit") == 1, "the tree itself is never touched"
    stryker = json.loads((out / "report.json").read_text())
    assert stryker["schemaVersion"] == "2" and set(stryker["thresholds"]) == {"high", "low"}
    mutants = {m["id"]: m for m in stryker["files"]["firmware/Clamp.cpp"]["mutants"]}
    assert {m["status"] for m in mutants.values()} <= STRYKER_STATUSES
    assert mutants[killed.id]["status"] == "Killed"
    assert sorted(mutants[killed.id]["killedBy"]) == ["unit:clamp.inside", "unit:clamp.limits"]
    assert mutants[survivor.id]["status"] == "Survived"
    assert mutants[broken.id]["status"] == "CompileError"
    assert json.loads((out / "mutants" / broken.id / "result.json").read_text())["compiled"] is False
    assert mutants[killed.id]["location"]["start"]["line"] == killed.line
    summary = (out / "report.txt").read_text()
    assert "not sampled: 1 product files the host build does not compile (firmware:" in summary
    assert stryker["config"]["not_sampled"] == ["firmware/OtherTarget.cpp"]
    assert "do not compile (dropped)   1" in summary
    assert "killed by unit tests alone         1/2 = 50.0 % (95 % CI 9.5-90.5 %)" in summary
    results = {
        m.id: json.loads((out / "mutants" / m.id / "result.json").read_text()) for m in (killed, survivor)
    }
    assert sorted(results[killed.id]["unit"]["selected"]) == ["clamp.inside", "clamp.limits"]
    assert results[survivor.id]["unit"]["selected"] == [], "no unit test executes its line: none run"
    assert results[survivor.id]["seconds"]["unit"] == 0.0
    assert "    -  return value * 3;\n    +  return value * 1;\n" in summary  # the survivor's diff
    # A second run reuses every result (same sources): nothing is built again; --again judges anew.
    result = json.loads((out / "mutants" / killed.id / "result.json").read_text())
    assert mutate.main(argv) == 0
    assert json.loads((out / "mutants" / killed.id / "result.json").read_text()) == result
    kept = out / "mutants" / killed.id / "result.json"
    kept.write_text(json.dumps({**result, "kept_from_before": True}))
    assert mutate.main([*argv, "--again"]) == 0
    again = json.loads(kept.read_text())
    assert "kept_from_before" not in again, "judged anew, not reused"
    assert again["unit"]["killed_by"] == result["unit"]["killed_by"]
    # Kept verdicts: only whole ones (without scenarios, the compile error alone); a run in a fresh
    # folder starts from them.
    assert mutate.main(["keep", "--out", str(out), "--kept", str(kept_file)]) == 0
    assert list(json.loads(kept_file.read_text())["mutants"]) == [broken.id]
    fresh = tmp_path / "fresh"
    assert mutate.main([str(fresh) if arg == str(out) else arg for arg in argv]) == 0
    started_from = json.loads((fresh / "mutants" / broken.id / "result.json").read_text())
    assert started_from == json.loads(kept_file.read_text())["mutants"][broken.id]


def test_a_mutant_s_scenarios_run_its_release_firmware(tmp_path: Path) -> None:
    """Built in a tree of its own (the configuration user-mode Linux runs: no ASan), kept in the
    mutant's folder, and built again if it went missing; the unit tests keep their tree."""
    survivor = tiny_mutant("return value * 3;", "return value * 1;")
    workspace = mutate.Workspace(
        tmp_path / "out", TINY, ("CMakeLists.txt", "firmware"), ("-DCMAKE_BUILD_TYPE=Debug",)
    )
    tree = mutate.scenario_tree_of(workspace)
    mutate.prepare(workspace, 2, tree)
    assert mutate.build_and_unit(workspace, [survivor], 2, tree) == [survivor]
    kept = workspace.mutant_dir(survivor) / mutate.SCENARIO_FIRMWARE / "joint-firmware"
    run = lambda: subprocess.run([kept], capture_output=True, text=True, check=True).stdout  # noqa: E731
    assert run() == "release 1\n", "the release build, with the mutant in it"
    assert tree.known(mutate.FIRMWARE_BINARIES) == ["bin/joint-firmware", "bin/head-firmware"]
    assert tree.compile(2, ["bin/joint-firmware"]).returncode == 0
    original = subprocess.run([tree.build / "bin" / "joint-firmware"], capture_output=True, text=True)
    assert original.stdout == "release 3\n", "the next build of the tree is the original again"
    kept.unlink()
    mutate.build_and_unit(workspace, [survivor], 2, tree)
    assert run() == "release 1\n", "built again for the scenarios; its unit result stands"


def test_a_file_the_host_build_never_compiles_is_not_sampled(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Its mutants would "survive" every test on an unmutated build: e.g. the bare-metal
    qemu-virt firmware, which only its own target builds."""
    other = tiny_mutant(
        "int other_target_scale(int value) { return value * 7; }",
        "int other_target_scale(int value) { return value * 1; }",
    )
    out = tmp_path / "out"
    argv = ["run", "--source", str(TINY), "--sources", "CMakeLists.txt", "firmware"]
    argv += ["--no-scenarios", "--jobs", "2", "--out", str(out), "--mutant", other.id]
    assert mutate.main(argv) == 2
    assert "no such mutant of a file the host build compiles" in capsys.readouterr().err
    listed = mutate.main(["list", "--source", str(TINY), "--out", str(out), "--mutants", "5"])
    assert listed == 0 and "OtherTarget" not in capsys.readouterr().out
    files = mutate.compiled_by(mutate.REPO / "build", mutate.REPO)
    assert "firmware/canopen/Node.cpp" in files and "firmware/canopen/Node.hpp" in files, "headers too"
    assert "firmware/platform/qemu-virt/FirmwareMain.cpp" not in files
    with pytest.raises(ValueError, match="run `make build` first"):
        mutate.compiled_by(tmp_path, TINY)


def test_only_scenarios_that_judge_the_firmware_under_test_judge_a_mutant(tmp_path: Path) -> None:
    """A rig check (pytest.ini's marker) runs a firmware it builds itself, and a scenario that
    fails on the unmutated firmware fails whatever the mutant: neither may count as a kill."""
    ids = mutate_scenarios.collect_scenarios(tmp_path)
    assert "tests/test_protection_rules.py::test_watchdog_trips_on_its_cycle_and_cuts_the_drive_there" in ids
    assert not [t for t in ids if t.startswith("tests/test_approved_traces.py")], "a rig check"
    assert "tests/test_two_worlds.py::test_velocity_hold_realtime" not in ids, "lockstep only"
    assert mutate_scenarios.scenarios_that_judge(ids, tmp_path) == ids, "no baseline record: all"
    (tmp_path / "coverage").mkdir()
    report.write_json(tmp_path / "coverage" / mutate_scenarios.BASELINE_FAILURES, {"failed": ids[:1]})
    assert mutate_scenarios.scenarios_that_judge(ids, tmp_path) == ids[1:]


JUNIT = """<testsuites><testsuite>
<testcase classname="tests.test_a" name="assertion"><failure message="AssertionError: duty 0.4" /></testcase>
<testcase classname="tests.test_b" name="trace">
  <failure message="the run differs from its approved trace x" /></testcase>
<testcase classname="tests.test_c" name="ok" />
<testcase classname="tests.test_d" name="starved"><error message="HostStarvedError: 2 s" /></testcase>
<testcase classname="tests.test_e" name="skipped"><skipped /></testcase>
</testsuite></testsuites>"""


def test_a_scenario_failure_is_its_assertions_or_its_trace(tmp_path: Path) -> None:
    junit = tmp_path / "scenarios.xml"
    junit.write_text(JUNIT)
    assert mutate_scenarios.outcomes(junit) == (
        ["tests/test_a.py::assertion"],
        ["tests/test_b.py::trace"],
        ["tests/test_c.py::ok"],
        ["tests/test_d.py::starved"],
    )


def test_a_survivor_costs_one_pass_and_a_trace_kill_asks_the_assertions_of_the_rest(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The traces are compared only after a scenario's assertions passed: a clean pass with the
    traces checked is a survivor of both layers."""
    order = ["a", "b", "c"]
    calls: list[tuple[list[str], list[str]]] = []

    def fake(outcome_of: dict[str, str]) -> None:
        def one_pass(folder: Path, ids: list[str], durations: dict, extra: list[str]) -> object:
            calls.append((list(ids), list(extra)))
            traces = mutate_scenarios.APPROVED_OFF not in extra
            done = mutate_scenarios.Pass([], [], [], None, False, 1.0)
            for t in ids:  # -x: the first failure stops the run
                kind = outcome_of.get(t, "pass")
                if kind == "pass" or (kind == "trace" and not traces):
                    done.passed.append(t)
                    continue
                (done.differed if kind == "trace" else done.failed).append(t)
                break
            return done

        monkeypatch.setattr(mutate_scenarios, "_one_pass", one_pass)

    fake({})
    scenarios, traces, why, _ = mutate_scenarios.judge(Path(), order, {}, approved=True)
    assert scenarios["killed_by"] == traces["killed_by"] == [] and why is None and len(calls) == 1
    calls.clear()
    fake({"b": "trace", "c": "assert"})
    scenarios, traces, _, seconds = mutate_scenarios.judge(Path(), order, {}, approved=True)
    assert traces["killed_by"] == ["b"] and scenarios["killed_by"] == ["c"] and seconds == 2.0
    assert calls[1] == (["b", "c"], [mutate_scenarios.APPROVED_OFF]), "a passed: not run again"
    calls.clear()
    fake({"a": "assert"})
    scenarios, traces, _, _ = mutate_scenarios.judge(Path(), order, {}, approved=True)
    assert scenarios["killed_by"] == traces["killed_by"] == ["a"] and len(calls) == 1


def outcome(
    mutant_id: str,
    unit: list[str] | None,
    scenarios: list[str] | None,
    compiled: bool = True,
    approved: list[str] | None = None,
) -> report.Outcome:
    return report.Outcome(
        mutant_id,
        "firmware/joint/modules/X.cpp",
        3,
        "a < b;\n",
        "a <= b;\n",
        "< ==> <=",
        compiled,
        unit,
        None,
        scenarios,
        None,
        approved if approved is not None else scenarios,
    )


def test_scores_count_each_layer_alone_and_drop_what_does_not_count() -> None:
    outcomes = [
        outcome("a", ["unit:t1"], []),
        outcome("b", [], ["s1"]),
        outcome("c", [], []),
        outcome("d", ["t2"], ["s2"]),
        outcome("e", None, None, compiled=False),
    ]
    outcomes.append(
        report.Outcome(
            "f", "firmware/core/Y.cpp", 1, "x\n", "y\n", "r", True, [], None, [], None, [], equivalent="same"
        )
    )
    s = report.scores(outcomes)
    assert (s.overall.killed, s.overall.total) == (3, 4)
    assert (s.unit.killed, s.scenarios.killed) == (2, 2)
    assert s.compile_errors == 1 and s.equivalent == 1
    assert s.by_component == {"joint/modules": report.Score(3, 4)}


def test_shards_side_by_side_in_one_folder_keep_their_plans_apart() -> None:
    shard = mutate.Selection(None, [], TINY, "", "report-shard-2-of-4", {})
    assert shard.plan_name == "report-shard-2-of-4-plan.json"
    assert mutate.Selection(None, [], TINY, "", "report", {}).plan_name == "plan.json"


def test_shards_reports_merge_into_the_whole() -> None:
    first = [outcome("a", ["t1"], []), outcome("b", [], [], approved=["s2"])]
    second = [outcome("c", [], ["s1"]), outcome("d", None, None, compiled=False)]
    sources = {"firmware/joint/modules/X.cpp": "a < b;\n"}
    merged = report.merge(
        [
            report.to_stryker(first, sources, {"shard": "1/2"}),
            report.to_stryker(second, sources, {"shard": "2/2"}),
        ]
    )
    whole = report.scores(report.from_stryker(merged))
    assert whole == report.scores(first + second)
    assert (whole.scenarios.killed, whole.approved.killed, whole.overall.killed) == (1, 2, 3)
    assert merged["config"]["merged_shards"] == ["1/2", "2/2"]


def test_an_equivalent_mutant_is_ignored(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    listed = tmp_path / "equivalent.toml"
    listed.write_text('[[equivalent]]\nid = "Clamp-1"\nchange = "x -> y"\nreason = "dead code"\n')
    monkeypatch.setattr(mutate, "EQUIVALENTS", listed)
    assert mutate.load_equivalents(listed) == {"Clamp-1": "dead code"}
    result = {
        "id": "Clamp-1",
        "path": "firmware/Clamp.cpp",
        "line": 1,
        "original": "x\n",
        "replacement": "y\n",
    }
    result |= {"rule": "r", "compiled": True, "unit": {"killed_by": [], "timeout": None}}
    assert mutate.outcome_of(result, mutate.load_equivalents(listed)).status == "Ignored"


def test_a_mutant_builds_only_its_firmware_and_the_tests_that_execute_its_line(tmp_path: Path) -> None:
    (tmp_path / "bin").mkdir()
    (tmp_path / "bin" / "fw_core_tests").touch()
    binaries = ["bin/joint-firmware"]
    assert mutate.needed_targets(tmp_path, binaries, ["fw_core_tests"]) == [
        "bin/joint-firmware",
        "bin/fw_core_tests",
    ]
    assert mutate.needed_targets(tmp_path, binaries, []) == binaries, "no unit test executes its line"
    assert mutate.needed_targets(tmp_path, binaries, None) is None, "no coverage record: everything"
    assert mutate.needed_targets(tmp_path, binaries, ["elsewhere_tests"]) is None, "not where ctest runs it"


def test_whole_verdicts_are_kept_and_start_a_fresh_run_while_their_file_is_unchanged(
    tmp_path: Path,
) -> None:
    root = tmp_path / "src"
    (root / "firmware").mkdir(parents=True)
    source = root / "firmware" / "A.cpp"
    source.write_text("int a() { return 1; }\n")
    digest = mutate.source_digest(root, "firmware/A.cpp")
    layer = {"killed_by": [], "timeout": None, "selected": 3}
    results = {
        "A-1": {
            "compiled": True,
            "unit": {**layer, "selected": ["x", "y"]},
            "scenarios": layer,
            "approved": layer,
        },
        "A-2": {"compiled": True, "unit": layer, "scenarios": None},  # its scenarios still to run
        "A-3": {"compiled": False},
    }
    out = tmp_path / "out"
    for mutant_id, result in results.items():
        whole = {"id": mutant_id, "path": "firmware/A.cpp", "source_sha1": digest, **result}
        report.write_json(out / "mutants" / mutant_id / "result.json", whole)
    kept = tmp_path / "judged.json"
    assert mutate_kept.keep(out, kept, commit="c0ffee") == (2, 2)
    entries = mutate_kept.load(kept)
    assert entries["A-1"]["unit"]["selected"] == 2 and entries["A-1"]["judged_at"] == "c0ffee"
    assert mutate_kept.keep(out, kept, commit="later") == (0, 2), "the same verdicts: nothing new"
    fresh = tmp_path / "fresh"
    assert mutate_kept.seed(fresh, root, ["A-1", "A-2", "A-3", "B-1"], kept) == 2
    assert json.loads((fresh / "mutants" / "A-1" / "result.json").read_text()) == entries["A-1"]
    assert not (fresh / "mutants" / "A-2").exists()
    source.write_text("int a() { return 2; }\n")
    assert mutate_kept.seed(tmp_path / "changed", root, ["A-1", "A-3"], kept) == 0, "judged again"
    kept.write_text(json.dumps({"format": 99, "mutants": {}}))
    with pytest.raises(ValueError, match="format 99"):
        mutate_kept.load(kept)
