"""The scenario layer of `make mutate` (run inside tools/with-vcan): the lockstep scenarios that
execute a mutant's line (mutate_coverage), against the mutant's firmware, killers first, `-x`.

Two passes at most: first with the approved traces checked (the plugin's default; it compares a
trace only after its scenario's own assertions passed, so a clean pass is a survivor of both
layers and costs one pass), then, only when a trace difference was the first failure, with the
traces off (`--hil-approved=off`) over the scenarios not yet passed, for the score of the
scenarios' own assertions. A plugin without `--hil-approved` (detected from `pytest --help`)
has no approved traces: one pass, and the second score is the first.

A hang is a kill only against the unmutated firmware's own time: in the scenarios a firmware
that hangs fails the lockstep HangGuard (asleep with TPDOs due, or its CPU spent without an
answer, where the unmutated firmware answers within milliseconds of CPU): a kill. The whole
scenario run's bound (HANG_FACTOR times the recorded durations plus a margin) is only a guard:
a loaded host made a survivor overrun it, so reaching it is no verdict and the mutant's
scenarios count as not run. A scenario that fails because the host was starved
(HostStarvedError) is no kill either: it is run again once, and counted as not run if it
starves again.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import mutate_coverage as coverage
import mutation_report as report
import scenario_shards
from mutate_mutants import REPO, load_equivalents

HANG_FACTOR = 3
HANG_MARGIN_S = 60.0
SCENARIO_WORKERS = 2
FIRMWARE_BINARIES = ("bin/joint-firmware", "bin/head-firmware", "bin/fw_linux_tests")
"""What a mutant's scenarios start, those of them its build has: the firmware, the head's beside
it (the head's scenarios), the SocketCAN port's googletest beside it (tests/test_socketcan_port.py
runs it on a real bus)."""
SCENARIO_CMAKE_ARGS = (
    "-DCMAKE_BUILD_TYPE=Release",
    "-DHIL_SANITIZE=OFF",
    "-DHIL_TESTS=OFF",
    "-DHIL_PORT_TESTS=ON",
)
"""The firmware a mutant's scenarios run: the configuration of `make build`'s build/release (the
Makefile's home of it), which make test's lockstep bus stage runs under user-mode Linux. An ASan
build cannot start there, and the micro-VM it needs emulates the CPU in software, several times
slower for the same scenarios (the commit that made this choice has the figures)."""
SCENARIO_FIRMWARE = "scenario-firmware"
"""A mutant's folder's subfolder with the firmware its scenarios run."""
APPROVED_OFF = "--hil-approved=off"
BASELINE_FAILURES = "baseline-failed.json"
"""The scenarios that failed on the unmutated (coverage) firmware, in the coverage folder: they fail
whatever a mutant does, so they judge none."""


def approved_option_known() -> bool:
    """Whether the pytest plugin has approved traces (and the option that turns them off)."""
    result = subprocess.run(
        [sys.executable, "-m", "pytest", "--help", "-p", "no:cacheprovider"],
        cwd=REPO,
        capture_output=True,
        text=True,
        check=False,
    )
    return "--hil-approved" in result.stdout


def collect_scenarios(out: Path) -> list[str]:
    """The lockstep scenarios' node ids (collected natively; the VM runs them)."""
    argv = [sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider"]
    argv += scenario_shards.mutation_selection_args()
    result = subprocess.run(argv, cwd=REPO, capture_output=True, text=True, check=False)
    ids = [line for line in result.stdout.splitlines() if "::" in line]
    if not ids:
        raise SystemExit(
            f"mutate: no lockstep scenario collected:\n{result.stdout[-2000:]}{result.stderr[-2000:]}"
        )
    report.write_json(out / "scenarios.json", {"ids": ids, "approved_option": approved_option_known()})
    return ids


def scenario_order(ids: Sequence[str], kills: Counter[str], durations: dict[str, float]) -> list[str]:
    """Those that killed most mutants so far first, then the short ones."""
    average = sum(durations.values()) / len(durations) if durations else 1.0
    return sorted(ids, key=lambda t: (-kills[t], durations.get(t, average), t))


def pytest_argv(ids: Sequence[str], junit: Path, extra: Sequence[str], stop_at_first: bool) -> list[str]:
    argv = [sys.executable, "-m", "pytest", *ids, "-q", "-n", str(SCENARIO_WORKERS)]
    argv += ["-p", "no:cacheprovider", f"--junitxml={junit}", *extra]
    return argv + (["-x"] if stop_at_first else [])


@dataclass
class Pass:
    """One run of scenarios against a mutant's firmware."""

    failed: list[str]
    """By their own assertions (or an error)."""
    differed: list[str]
    """Their assertions passed, their run differs from its approved trace."""
    passed: list[str]
    timeout: str | None
    """Why the run was stopped at its bound: no verdict."""
    starved: bool
    """A failure was only the host starving the scenario: no verdict."""
    seconds: float


DIFFERS = "the run differs from its approved trace"
"""How the plugin's failure of a trace difference begins (hilrig.pytest_plugin.approved); it
compares only after the scenario's own assertions passed."""
NO_VERDICT = ("HostStarvedError", "no approved trace", "approved trace ")
"""Failures that say nothing of the mutant: a starved host, a missing or unreadable baseline."""


def run_scenarios(
    firmware: Path,
    ids: Sequence[str],
    durations: dict[str, float],
    out: Path,
    extra: Sequence[str] = (),
    env_extra: dict[str, str] | None = None,
    stop_at_first: bool = True,
) -> Pass:
    """Scenarios `ids` against `firmware`."""
    expected = sum(durations.get(t, 10.0) for t in ids) / SCENARIO_WORKERS
    timeout_s = HANG_FACTOR * expected + HANG_MARGIN_S
    junit = out / "scenarios.xml"
    junit.unlink(missing_ok=True)
    env = dict(
        os.environ,
        CI="true",  # a missing approved trace fails instead of being written from a mutant
        HIL_FIRMWARE=str(firmware),
        HIL_OUT_DIR=str(out / "scenario-out"),
        HIL_SCENARIO_ORDER="given",
        **(env_extra or {}),
    )
    started = time.monotonic()
    with open(out / "scenarios.log", "a") as log:
        process = subprocess.Popen(
            pytest_argv(ids, junit, extra, stop_at_first),
            cwd=REPO,
            env=env,
            stdout=log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
        try:
            process.wait(timeout_s)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
            why = (
                f"scenarios past {timeout_s:.0f} s ({HANG_FACTOR}x the unmutated firmware's "
                f"{expected:.0f} s + {HANG_MARGIN_S:.0f} s)"
            )
            return Pass([], [], [], why, False, time.monotonic() - started)
        except BaseException:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
            raise
    seconds = time.monotonic() - started
    failed, differed, passed, no_verdict = outcomes(junit)
    if process.returncode not in (0, 1) and not failed and not differed and not no_verdict:
        failed.append(f"pytest exit {process.returncode}")
    starved = bool(no_verdict) and not failed and not differed
    return Pass(failed, differed, passed, None, starved, seconds)


def outcomes(junit: Path) -> tuple[list[str], list[str], list[str], list[str]]:
    """A run's scenarios from its JUnit XML: (failed by their assertions, their trace differs,
    passed, failed saying nothing of the mutant)."""
    failed: list[str] = []
    differed: list[str] = []
    passed: list[str] = []
    no_verdict: list[str] = []
    if junit.exists():
        for case in ET.parse(junit).getroot().iter("testcase"):
            name = f"{case.get('classname', '').replace('.', '/')}.py::{case.get('name')}"
            problem = case.find("failure")
            if problem is None:
                problem = case.find("error")
            if problem is None:
                if case.find("skipped") is None:
                    passed.append(name)
                continue
            text = (problem.get("message") or "") + (problem.text or "")
            if DIFFERS in text:
                differed.append(name)
            elif any(marker in text for marker in NO_VERDICT):
                no_verdict.append(name)
            else:
                failed.append(name)
    return failed, differed, passed, no_verdict


def coverage_command(out: Path) -> int:
    """Inside the VM: every lockstep scenario once against the coverage build's firmware, each
    scenario's counters in a folder of its own (this run's plugin: mutate_coverage)."""
    listed = json.loads((out / "scenarios.json").read_text())
    durations = json.loads((REPO / scenario_shards.DURATIONS).read_text())
    counters = out / "coverage" / "scenario-counters"
    shutil.rmtree(counters, ignore_errors=True)
    counters.mkdir(parents=True)
    tools = str(Path(__file__).resolve().parent)
    env = {
        coverage.PREFIX_VARIABLE: str(counters),
        "PYTHONPATH": os.pathsep.join(p for p in (tools, os.environ.get("PYTHONPATH", "")) if p),
    }
    folder = out / "coverage"
    done = run_scenarios(
        folder / "build" / FIRMWARE_BINARIES[0],
        listed["ids"],
        durations,
        folder,
        ["-p", "mutate_coverage"] + ([APPROVED_OFF] if listed["approved_option"] else []),
        env,
        stop_at_first=False,
    )
    print(f"mutate: coverage of {len(listed['ids'])} scenarios recorded ({done.seconds:.0f} s)", flush=True)
    if done.failed or done.timeout:
        print(
            f"mutate: on the coverage build {done.timeout or 'these failed'}: {', '.join(done.failed[:8])}",
            flush=True,
        )
    report.write_json(folder / BASELINE_FAILURES, {"failed": done.failed})
    return 0


def _one_pass(folder: Path, order: Sequence[str], durations: dict[str, float], extra: Sequence[str]) -> Pass:
    for attempt in (1, 2):
        done = run_scenarios(folder / SCENARIO_FIRMWARE / "joint-firmware", order, durations, folder, extra)
        if not done.starved:
            break
        print(f"mutate: {folder.name}: the host starved the scenarios (attempt {attempt})", flush=True)
    return done


def judge(
    folder: Path, order: Sequence[str], durations: dict[str, float], approved: bool
) -> tuple[dict | None, dict | None, str | None, float]:
    """A mutant's two verdicts: (its scenarios' own assertions, with the approved traces too, why
    there is none, seconds). First with the traces (a survivor costs one pass: a trace is compared
    only after its scenario's assertions passed), then, when a trace difference was the first
    failure, with the traces off over the scenarios that had not passed yet."""
    if not order:
        none = {"killed_by": [], "timeout": None, "selected": 0}
        return none, none, None, 0.0
    first = _one_pass(folder, order, durations, [] if approved else [APPROVED_OFF])
    if first.starved or first.timeout:
        return None, None, first.timeout or "the host starved the scenarios twice", first.seconds
    with_traces = {"killed_by": first.failed + first.differed, "timeout": None, "selected": len(order)}
    if first.failed or not first.differed:
        return {**with_traces, "killed_by": first.failed}, with_traces, None, first.seconds
    rest = [t for t in order if t not in set(first.passed)]
    second = _one_pass(folder, rest, durations, [APPROVED_OFF])
    seconds = first.seconds + second.seconds
    if second.starved or second.timeout:
        return None, with_traces, second.timeout or "the host starved the scenarios twice", seconds
    return {"killed_by": second.failed, "timeout": None, "selected": len(order)}, with_traces, None, seconds


def scenarios_that_judge(ids: Sequence[str], out: Path) -> list[str]:
    """`ids` without those that failed on the unmutated firmware (the coverage run's record)."""
    failing_path = out / "coverage" / BASELINE_FAILURES
    failing = set(json.loads(failing_path.read_text())["failed"]) if failing_path.exists() else set()
    if failing:
        print(
            f"mutate: {len(failing)} scenarios fail on the unmutated firmware and judge no mutant: "
            f"{', '.join(sorted(failing))}",
            flush=True,
        )
    return [t for t in ids if t not in failing]


def scenarios_command(out: Path, plan_name: str = "plan.json") -> int:
    """Inside the VM: the scenario layer for every built mutant of the run's plan that has none."""
    plan = json.loads((out / plan_name).read_text())
    listed = json.loads((out / "scenarios.json").read_text())
    ids, approved = listed["ids"], listed["approved_option"]
    durations = json.loads((REPO / scenario_shards.DURATIONS).read_text())
    record_path = out / "coverage" / "coverage.json"
    record = (
        coverage.Coverage.from_json(json.loads(record_path.read_text())) if record_path.exists() else None
    )
    ids = scenarios_that_judge(ids, out)
    kills_path = out / "kills.json"
    kills: Counter[str] = Counter(json.loads(kills_path.read_text()) if kills_path.exists() else {})
    equivalent = load_equivalents()
    todo = [m for m in plan["mutants"] if m not in equivalent and _needs_scenarios(out / "mutants" / m)]
    missing = [m for m in todo if not (out / "mutants" / m / SCENARIO_FIRMWARE / "joint-firmware").exists()]
    if missing:  # never a kill: a scenario against no firmware fails whatever the mutant does
        print(f"mutate: no firmware kept for {', '.join(missing)}: run `run` again to build them", flush=True)
        todo = [m for m in todo if m not in missing]
    for number, mutant_id in enumerate(todo, 1):
        folder = out / "mutants" / mutant_id
        result = json.loads((folder / "result.json").read_text())
        selected = record.covering(result["path"], result["line"], coverage.SCENARIO) if record else None
        recorded = set(record.tests) if record else set()
        chosen = (  # a scenario the record does not know (added since) may execute anything
            ids
            if selected is None
            else [t for t in ids if t in set(selected) or coverage.SCENARIO + t not in recorded]
        )
        order = scenario_order(chosen, kills, durations)
        scenarios, with_traces, not_run, seconds_total = judge(folder, order, durations, approved)
        layers = {"scenarios": scenarios, "approved": with_traces}
        kills.update({t for layer in layers.values() for t in (layer or {}).get("killed_by", [])})
        if not_run:
            result["scenarios_not_run"] = not_run
        if not (layers.get("approved") or {}).get("killed_by"):
            shutil.rmtree(folder / "scenario-out", ignore_errors=True)  # a survivor's traces: not kept
        result["scenarios"], result["approved"] = layers["scenarios"], layers.get("approved")
        if layers["scenarios"] is not None:
            result.setdefault("seconds", {})["scenarios"] = round(seconds_total, 1)
        report.write_json(kills_path, dict(kills))
        report.write_json(folder / "result.json", result)
        killed = (layers.get("approved") or {}).get("killed_by") or []
        verdict = "killed by " + killed[0] if killed else result.get("scenarios_not_run", "survived")
        print(
            f"mutate: scenarios {number}/{len(todo)} {mutant_id}: {verdict} "
            f"({len(order)} of {len(ids)} scenarios execute its line, {seconds_total:.0f} s)",
            flush=True,
        )
    return 0


def _needs_scenarios(folder: Path) -> bool:
    result_path = folder / "result.json"
    if not result_path.exists():
        return False
    result = json.loads(result_path.read_text())
    return result.get("compiled", False) and result.get("scenarios") is None  # none yet, or starved
