"""The shards of `make test SHARD=K/N` partition the bus-level scenarios: for N = 2..5 every
scenario runs in exactly one shard, also one with no recorded duration.

Everything is collected natively (no bus) with the arguments tools/run-tests passes, taken from
tools/scenario_shards.py. One collection per selection records every group pytest-split's
algorithm makes for each N; a few real `--splits/--group` collections check that this plan is what
the shards select.
"""

from __future__ import annotations

import fcntl
import json
import os
import pickle
from collections import Counter
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path

import pytest
from tool_loader import load_tool

shards = load_tool("scenario_shards")
# Real --splits/--group collections that must match the plan: the second lockstep shard of two,
# and of six real-time shards (fewer real-time scenarios than that: a shard gets none, pytest's
# exit 5) the first the plan leaves empty and the first it does not.
LOCKSTEP_CROSS_CHECK = shards.Shard(2, 2)
REALTIME_SPLITS = 6
SPLITS = [2, 3, 4, REALTIME_SPLITS]


@pytest.fixture(scope="session")
def durations_missing_some(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[str]]:
    """A copy of the committed durations without the first scenario of each selection: what a
    newly added scenario looks like to pytest-split."""
    recorded: dict[str, float] = json.loads((shards.REPO / shards.DURATIONS).read_text())
    lockstep_id = next(nodeid for nodeid in sorted(recorded) if "realtime" not in nodeid)
    realtime_id = "tests/test_two_worlds.py::test_velocity_hold_realtime"
    assert realtime_id in recorded and lockstep_id in recorded
    path = tmp_path_factory.mktemp("durations") / "without-two"
    path.write_text(json.dumps({k: v for k, v in recorded.items() if k not in (lockstep_id, realtime_id)}))
    return path, [lockstep_id, realtime_id]


@pytest.fixture(scope="session")
def collected(
    durations_missing_some: tuple[Path, list[str]], tmp_path_factory: pytest.TempPathFactory
) -> dict[object, shards.Collected]:
    """Every collection the tests compare (some ten pytest start-ups), made once in a run: under
    pytest-xdist the first worker to ask makes them and the others read its result (their
    tests of this module land on both; xdist_group does not hold them together here)."""
    run = os.environ.get("PYTEST_XDIST_TESTRUNUID")
    if run is None:
        return _collect_all(durations_missing_some)
    shared = tmp_path_factory.getbasetemp().parent  # every worker's base folder is in it
    made = shared / f"scenario-shards-{run}.pickle"
    with (shared / f"scenario-shards-{run}.lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        if made.exists():
            return pickle.loads(made.read_bytes())
        result = _collect_all(durations_missing_some)
        made.write_bytes(pickle.dumps(result))
        return result


def _collect_all(durations_missing_some: tuple[Path, list[str]]) -> dict[object, shards.Collected]:
    without_some, _ = durations_missing_some
    jobs: dict[object, tuple[list[str], list[int] | None]] = {"suite": (shards.SCENARIOS, None)}
    for selection in shards.SELECTIONS:
        for variant, durations in (("recorded", shards.DURATIONS), ("missing", without_some)):
            args = shards.selection_args(selection) + shards.split_options(durations)
            jobs[("plan", variant, selection)] = (args, SPLITS)
    jobs[("shard", "lockstep", str(LOCKSTEP_CROSS_CHECK))] = (
        shards.selection_args("lockstep", LOCKSTEP_CROSS_CHECK),
        None,
    )
    with ThreadPoolExecutor(max_workers=os.cpu_count() or 2) as pool:
        futures: dict[object, Future[shards.Collected]] = {
            key: pool.submit(shards.collect, args, splits) for key, (args, splits) in jobs.items()
        }
        collected = {key: future.result() for key, future in futures.items()}
        groups = collected[("plan", "recorded", "realtime")].groups[REALTIME_SPLITS]
        empty = next((k for k, group in enumerate(groups, 1) if not group), None)
        full = next(k for k, group in enumerate(groups, 1) if group)
        checks = [shards.Shard(k, REALTIME_SPLITS) for k in (empty, full) if k is not None]
        more = {
            ("shard", "realtime", str(shard)): pool.submit(
                shards.collect, shards.selection_args("realtime", shard), None
            )
            for shard in checks
        }
        collected.update({key: future.result() for key, future in more.items()})
        return collected


def test_the_selections_run_tests_makes_cover_the_suite_once(
    collected: dict[object, shards.Collected],
) -> None:
    suite = collected["suite"].selected
    lockstep = collected[("plan", "recorded", "lockstep")].selected
    realtime = collected[("plan", "recorded", "realtime")].selected
    assert len(suite) > 10 and realtime, "the suite or its real-time selection came out empty"
    assert Counter(lockstep + realtime) == Counter(suite)


@pytest.mark.parametrize("variant", ["recorded", "missing"])
def test_every_scenario_runs_in_exactly_one_shard(
    collected: dict[object, shards.Collected], durations_missing_some: tuple[Path, list[str]], variant: str
) -> None:
    suite = collected["suite"].selected
    for count in SPLITS:
        per_shard: list[list[str]] = [[] for _ in range(count)]
        for selection in shards.SELECTIONS:
            plan = collected[("plan", variant, selection)]
            groups = plan.groups[count]
            assert len(groups) == count
            ran = Counter(nodeid for group in groups for nodeid in group)
            assert ran == Counter(plan.selected), f"{selection}, N={count}: not each scenario exactly once"
            for index, group in enumerate(groups):
                per_shard[index] += group
        assert Counter(nodeid for shard in per_shard for nodeid in shard) == Counter(suite)
        assert all(per_shard), f"N={count}: a shard with no scenario at all"
        if variant == "missing":
            _, unrecorded = durations_missing_some
            for nodeid in unrecorded:
                assert sum(nodeid in shard for shard in per_shard) == 1, f"N={count}: {nodeid}"


def test_the_shards_select_what_the_plan_says(collected: dict[object, shards.Collected]) -> None:
    checked = [key for key in collected if isinstance(key, tuple) and key[0] == "shard"]
    assert len(checked) == 3, f"a lockstep shard, an empty and a full real-time shard: {checked}"
    for _, selection, text in checked:
        shard = shards.parse_shard(text)
        selected = collected[("shard", selection, text)].selected
        planned = collected[("plan", "recorded", selection)].groups[shard.count][shard.index - 1]
        assert selected == planned, f"{selection} shard {shard}"
    # The case run-tests must skip rather than run into pytest's exit 5 (more shards than
    # real-time scenarios).
    assert any(not collected[key].selected for key in checked if key[1] == "realtime")


@pytest.mark.parametrize("text", ["1/1", "1/2", "2/2", "5/5", "12/40"])
def test_shard_specs_that_name_a_shard(text: str) -> None:
    assert str(shards.parse_shard(text)) == text


@pytest.mark.parametrize("text", ["3/2", "0/2", "1/0", "01/2", "x", "", "1/2/3", "-1/2", "1 / 2", "a/b"])
def test_shard_specs_that_do_not(text: str) -> None:
    with pytest.raises(ValueError, match="SHARD="):
        shards.parse_shard(text)


def test_durations_come_from_junit_by_pytests_own_names(tmp_path: Path) -> None:
    in_class = "tests/test_conformance_cia301.py::TestNmt_7_2_8::test_reset"
    plain = "tests/test_joint.py::test_step[fast.one]"
    junit = tmp_path / "scenarios.xml"
    junit.write_text(
        '<testsuites><testsuite name="pytest">'
        '<testcase classname="tests.test_conformance_cia301.TestNmt_7_2_8" name="test_reset" time="8.25"/>'
        '<testcase classname="tests.test_joint" name="test_step[fast.one]" time="1.5"/>'
        "</testsuite></testsuites>"
    )
    assert shards.durations_from_junit([junit], [in_class, plain]) == {in_class: 8.25, plain: 1.5}
    with pytest.raises(ValueError, match="no time for 1 scenarios"):
        shards.durations_from_junit([junit], [in_class, plain, "tests/test_new.py::test_x"])
    with pytest.raises(ValueError, match="is no scenario"):
        shards.durations_from_junit([junit], [in_class])


def test_the_durations_file_is_written_whole(tmp_path: Path) -> None:
    path = tmp_path / ".test_durations"
    path.write_text("old")
    shards.write_atomically(path, {"tests/test_a.py::test_b": 2.0})
    assert json.loads(path.read_text()) == {"tests/test_a.py::test_b": 2.0}
    assert [p.name for p in tmp_path.iterdir()] == [".test_durations"]


def test_counts_are_the_plans_groups_of_the_selection_as_run_tests_narrows_it(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # The plan is what --splits/--group select (test_the_shards_select_what_the_plan_says): here,
    # that `counts` collects the same selection, with $HIL_PYTEST_ARGS, and prints each group's size.
    asked: list[tuple[list[str], list[int] | None]] = []

    def collect(args: list[str], plan_splits: list[int] | None = None) -> shards.Collected:
        asked.append((args, plan_splits))
        return shards.Collected(selected=["a", "b", "c"], groups={3: [["a", "b"], [], ["c"]]})

    monkeypatch.setattr(shards, "collect", collect)
    monkeypatch.setenv("HIL_PYTEST_ARGS", "-k 'joint or robot'")
    assert shards.main(["scenario_shards.py", "counts", "lockstep", "3"]) == 0
    assert capsys.readouterr().out.split() == ["2", "0", "1"]
    expected = shards.selection_args("lockstep") + shards.split_options() + ["-k", "joint or robot"]
    assert asked == [(expected, [3])]
    assert shards.main(["scenario_shards.py", "counts", "lockstep", "0"]) == 2
    assert "'0' is not a number of groups" in capsys.readouterr().err
