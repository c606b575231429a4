"""`make mutate` (tools/mutate.py): the firmware's mutants, their seeded sample and its shards,
and a whole run of the build and unit-test layers on a tiny CMake tree (mutate_tiny: one product
file, two unit tests), down to the report in Stryker's schema and the merge of shards."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

TOOLS = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(TOOLS))
import mutate  # noqa: E402
import mutation_report as report  # noqa: E402
from scenario_shards import parse_shard  # noqa: E402

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


def test_the_sample_is_seeded_and_its_shards_partition_it() -> None:
    everything = mutate.all_mutants(mutate.REPO, mutate.product_files(mutate.REPO))
    assert len({m.id for m in everything}) == len(everything), "mutant ids must be unique"
    first = mutate.sample(everything, 40, seed=5)
    assert [m.id for m in first] == [m.id for m in mutate.sample(everything, 40, seed=5)]
    assert [m.id for m in first] != [m.id for m in mutate.sample(everything, 40, seed=6)]
    for count in (2, 3, 7):
        shards = [mutate.shard_of(first, parse_shard(f"{k}/{count}")) for k in range(1, count + 1)]
        ids = [m.id for shard in shards for m in shard]
        assert sorted(ids) == sorted(m.id for m in first)


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
    broken = tiny_mutant("return duty;", "return duty; break;")
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
    argv += ["--no-scenarios", "--jobs", "2", "--out", str(out)]
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
    assert mutants[killed.id]["location"]["start"]["line"] == killed.line
    summary = (out / "report.txt").read_text()
    assert "do not compile (dropped)   1" in summary
    assert "killed by unit tests alone         1/2 = 50.0 %" in summary
    assert "    -  return value * 3;\n    +  return value * 1;\n" in summary  # the survivor's diff
    # A second run reuses every result (same sources): nothing is built again.
    result = json.loads((out / "mutants" / killed.id / "result.json").read_text())
    assert mutate.main(argv) == 0
    assert json.loads((out / "mutants" / killed.id / "result.json").read_text()) == result


def outcome(
    mutant_id: str, unit: list[str] | None, scenarios: list[str] | None, compiled: bool = True
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
            "f", "firmware/core/Y.cpp", 1, "x\n", "y\n", "r", True, [], None, [], None, equivalent="same"
        )
    )
    s = report.scores(outcomes)
    assert (s.overall.killed, s.overall.total) == (3, 4)
    assert (s.unit.killed, s.scenarios.killed) == (2, 2)
    assert s.compile_errors == 1 and s.equivalent == 1
    assert s.by_component == {"joint/modules": report.Score(3, 4)}


def test_shards_reports_merge_into_the_whole() -> None:
    first = [outcome("a", ["t1"], []), outcome("b", [], [])]
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
