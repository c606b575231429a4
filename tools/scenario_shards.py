"""Shards of the bus-level scenarios for CI runners, split by pytest-split from measured durations.

`make test SHARD=K/N` runs shard K of N: tools/run-tests runs the scenarios in two pytest
invocations (SELECTIONS: the lockstep ones in parallel, then the real-time ones alone) with the
arguments `selection_args` spells here, so pytest-split keeps group K of each. This module is the one
place that spells them; the partition test (tools/tests/test_scenario_shards.py) checks them.

    scenario_shards.py check K/N                   exit 2 with one line unless K/N names a shard
    scenario_shards.py args SELECTION [K/N]        the pytest arguments of one invocation, one a line
    scenario_shards.py count SELECTION K/N         how many scenarios it selects (native collection,
                                                   with $HIL_PYTEST_ARGS as run-tests adds them)
    scenario_shards.py counts SELECTION N          the same for each K of 1..N, one a line, from one
                                                   collection (pytest-split's plan of N groups)
    scenario_shards.py durations OUT JUNIT_XML...  write the durations file from a full run

Loaded as a pytest plugin (`-p scenario_shards` with tools/ on PYTHONPATH) it records what a
collection selected and, for --shard-plan-splits, every group pytest-split's algorithm makes.
Imports only the standard library at module level: the Makefile checks SHARD with the system
python3 before the venv exists.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import pytest

REPO = Path(__file__).resolve().parent.parent
# The -m expression of each pytest invocation of the bus stage, in the order run-tests runs them.
SELECTIONS: dict[str, str] = {"lockstep": "not realtime", "realtime": "realtime"}
# Relative to the repository (run-tests and the VM both run there): pytest-split's JSON format,
# {"nodeid": seconds}, measured by `make durations`.
DURATIONS = Path("tests/.test_durations")
# Not scenarios: the browser checks of the scenarios' traces, run natively after the bus stage
# (tools/run-tests stage 4), where Chromium runs at full speed.
BROWSER_TESTS = Path("tests/browser")
SCENARIOS = ["tests", f"--ignore={BROWSER_TESTS}"]
"""Every scenario of the bus stage, before a selection or a shard narrows it."""
# least_duration: longest scenario first onto the least loaded shard, ties broken by name, so the
# shards come out even whatever the collection order. duration_based_chunks cuts the collection
# order into runs and can leave the last shards empty while the first carries the long tests.
ALGORITHM = "least_duration"
# pytest's "no tests collected": a legitimate answer to "which scenarios does this group hold".
EXIT_NO_TESTS_COLLECTED = 5


@dataclass(frozen=True)
class Shard:
    index: int  # 1-based, as pytest-split's --group
    count: int

    def __str__(self) -> str:
        return f"{self.index}/{self.count}"


def parse_shard(text: str) -> Shard:
    match = re.fullmatch(r"([1-9][0-9]*)/([1-9][0-9]*)", text)
    if not match:
        raise ValueError(f"SHARD={text!r} is not K/N (e.g. 1/2: the first of two shards)")
    index, count = int(match[1]), int(match[2])
    if index > count:
        raise ValueError(f"SHARD={text}: there is no shard {index} of {count} (K/N with 1 <= K <= N)")
    return Shard(index, count)


def selection_args(selection: str, shard: Shard | None = None, durations: Path = DURATIONS) -> list[str]:
    """What one bus-stage invocation passes to pytest to select its scenarios (run-tests adds
    the output and parallelism options)."""
    args = [*SCENARIOS, "-m", SELECTIONS[selection]]
    if shard is not None:
        args += [f"--splits={shard.count}", f"--group={shard.index}", *split_options(durations)]
    return args


MUTATION_SELECTION = f"({SELECTIONS['lockstep']}) and not rig_check"
"""The lockstep scenarios that judge the firmware under test ($HIL_FIRMWARE): `make mutate`'s. A
rig check (pytest.ini) runs a firmware it builds itself, so it would fail or pass whatever the
mutant is."""


def mutation_selection_args() -> list[str]:
    return [*SCENARIOS, "-m", MUTATION_SELECTION]


def split_options(durations: Path = DURATIONS) -> list[str]:
    """How pytest-split splits, without which group to keep (a plan collection takes these too)."""
    return [f"--splitting-algorithm={ALGORITHM}", f"--durations-path={durations}"]


def parse_count(text: str) -> int:
    if not re.fullmatch(r"[1-9][0-9]*", text):
        raise ValueError(f"{text!r} is not a number of groups (1 or more)")
    return int(text)


def plan_groups(selection: str, count: int) -> list[list[str]]:
    """The scenarios of each of `count` groups of `selection` (with $HIL_PYTEST_ARGS), from one
    collection: the plan pytest-split's algorithm makes, which is what `--splits=count --group=K`
    selects (the partition test checks that)."""
    extra = shlex.split(os.environ.get("HIL_PYTEST_ARGS", ""))
    return collect(selection_args(selection) + split_options() + extra, plan_splits=[count]).groups[count]


@dataclass
class Collected:
    selected: list[str]  # nodeids, after -m, -k and any --splits/--group
    groups: dict[int, list[list[str]]]  # N -> the nodeids of each of its groups, for plan_splits


def collect(args: list[str], plan_splits: list[int] | None = None) -> Collected:
    """Collect natively (no bus needed) with these pytest arguments: what they select and, for
    each N of plan_splits, the groups pytest-split's algorithm makes of that selection."""
    with tempfile.TemporaryDirectory() as scratch:
        record = Path(scratch) / "collected.json"
        command = [sys.executable, "-m", "pytest", *args, "--collect-only", "-q", "-p", "no:cacheprovider"]
        command += ["-p", "scenario_shards", f"--shard-record={record}"]
        if plan_splits:
            command.append(f"--shard-plan-splits={','.join(map(str, plan_splits))}")
        env = dict(
            os.environ,
            PYTHONPATH=os.pathsep.join(
                filter(None, [str(Path(__file__).parent), os.environ.get("PYTHONPATH")])
            ),
        )
        done = subprocess.run(command, cwd=REPO, env=env, capture_output=True, text=True, check=False)
        if done.returncode not in (0, EXIT_NO_TESTS_COLLECTED) or not record.exists():
            raise RuntimeError(
                f"collection failed (exit {done.returncode}): {shlex.join(command)}\n"
                f"{done.stdout}{done.stderr}"
            )
        recorded = json.loads(record.read_text())
        groups = {int(count): groups for count, groups in recorded.get("groups", {}).items()}
        return Collected(selected=recorded["selected"], groups=groups)


def junit_key(nodeid: str) -> tuple[str, str]:
    """The (classname, name) pytest's JUnit XML gives this test: its own mangling, so the mapping
    cannot drift from what pytest writes (tests/a.py::TestC::test_x -> tests.a.TestC, test_x)."""
    from _pytest.junitxml import mangle_test_address

    names = mangle_test_address(nodeid)
    return ".".join(names[:-1]), names[-1]


def durations_from_junit(junit_paths: list[Path], scenario_ids: list[str]) -> dict[str, float]:
    """Seconds per scenario (setup + call + teardown, what both JUnit and pytest-split count) from
    a run's JUnit XML; every scenario of the suite must be there and nothing else."""
    by_key = {junit_key(nodeid): nodeid for nodeid in scenario_ids}
    durations: dict[str, float] = {}
    for path in junit_paths:
        for case in ET.parse(path).getroot().iter("testcase"):
            key = (case.get("classname", ""), case.get("name", ""))
            if key not in by_key:
                raise ValueError(f"{path}: test case {'::'.join(key)} is no scenario of tests/ collected now")
            nodeid = by_key[key]
            durations[nodeid] = round(durations.get(nodeid, 0.0) + float(case.get("time", "0")), 3)
    missing = sorted(set(scenario_ids) - set(durations))
    if missing:
        raise ValueError(f"no time for {len(missing)} scenarios (not a full run?): {', '.join(missing)}")
    return durations


def write_atomically(path: Path, durations: dict[str, float]) -> None:
    """Replace the file whole: an interrupted refresh leaves the old durations, never half a file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile("w", dir=path.parent, prefix=path.name, delete=False) as out:
        json.dump(durations, out, sort_keys=True, indent=4)
        out.write("\n")
    os.replace(out.name, path)


# The plugin half: loaded into the collection subprocess of `collect`.


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("scenario_shards", "tools/scenario_shards.py (collection records)")
    group.addoption("--shard-record", help="write the selected nodeids (and a shard plan) as JSON here")
    group.addoption("--shard-plan-splits", default="", help="comma-separated N: record every group of N")


def pytest_collection_finish(session: pytest.Session) -> None:
    # After every pytest_collection_modifyitems (-m, -k, and pytest-split's own --splits).
    config = session.config
    record = config.getoption("shard_record")
    if not record:
        return
    result: dict[str, object] = {"selected": [item.nodeid for item in session.items]}
    splits = [int(text) for text in config.getoption("shard_plan_splits").split(",") if text]
    if splits:
        from pytest_split.algorithms import Algorithms

        path = Path(config.getoption("durations_path"))
        durations = json.loads(path.read_text()) if path.exists() else {}
        algorithm = Algorithms[config.getoption("splitting_algorithm")].value
        result["groups"] = {
            str(count): [
                [item.nodeid for item in group.selected]
                for group in algorithm(count, session.items, durations)
            ]
            for count in splits
        }
    Path(record).write_text(json.dumps(result))


def main(argv: list[str]) -> int:
    usage = (
        "usage: scenario_shards.py check K/N | args SELECTION [K/N] | count SELECTION K/N"
        " | counts SELECTION N | durations OUT JUNIT_XML..."
    )
    if len(argv) < 2:
        print(usage, file=sys.stderr)
        return 2
    command, rest = argv[1], argv[2:]
    try:
        if command == "check" and len(rest) == 1:
            parse_shard(rest[0])
        elif command == "args" and len(rest) in (1, 2) and rest[0] in SELECTIONS:
            print("\n".join(selection_args(rest[0], parse_shard(rest[1]) if len(rest) == 2 else None)))
        elif command == "count" and len(rest) == 2 and rest[0] in SELECTIONS:
            extra = shlex.split(os.environ.get("HIL_PYTEST_ARGS", ""))
            print(len(collect(selection_args(rest[0], parse_shard(rest[1])) + extra).selected))
        elif command == "counts" and len(rest) == 2 and rest[0] in SELECTIONS:
            print("\n".join(str(len(group)) for group in plan_groups(rest[0], parse_count(rest[1]))))
        elif command == "durations" and len(rest) >= 2:
            scenario_ids = collect(SCENARIOS).selected
            durations = durations_from_junit([Path(p) for p in rest[1:]], scenario_ids)
            write_atomically(Path(rest[0]), durations)
            print(
                f"durations: {len(durations)} scenarios, {sum(durations.values()):.0f} s in all -> {rest[0]}"
            )
        else:
            print(usage, file=sys.stderr)
            return 2
    except (ValueError, RuntimeError, OSError, ET.ParseError) as error:
        print(f"{Path(argv[0]).name}: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
