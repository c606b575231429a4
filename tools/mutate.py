"""Mutation testing of the firmware: how many small, realistic changes to its product code do the
tests reject? `make mutate` runs it; the verdict is in tools/mutation_report.py.

    tools/mutate.py run [--mutants N] [--seed S] [--shard K/N] [--out DIR] [--no-scenarios]
    tools/mutate.py list [--mutants N] [--seed S] [--shard K/N]      the sample, nothing built
    tools/mutate.py report [--mutants N] [--seed S] [--shard K/N]    the report from the results so far
    tools/mutate.py merge REPORT... --out DIR                         shards' reports as one
    tools/mutate.py scenarios --out DIR                               (inside tools/with-vcan)

The mutants come from universalmutator's C++ rules (PyPI, maintained, regexp-based: operators
swapped, comparisons flipped, conditions negated or forced, constants moved, statements dropped),
applied to one line of one product file at a time: firmware/ without its tests, benchmarks,
fuzzers and test doubles (NOT_PRODUCT). Every mutant of every product file, in a stable order,
then a seeded sample of N (SEED); a shard K/N takes every N-th of the sample from the K-th, so the
shards of one sample add up to it whatever N is, and `merge` puts their reports together.

Each sampled mutant, in a copy of the sources (build/mutate/src: the checkout is never touched,
and Ctrl-C leaves nothing half-mutated), is built incrementally in the test configuration
(ASan + UBSan); a mutant that does not compile is dropped and counted. Then the C++ unit tests
(ctest), then, in one micro-VM for the whole sample, the bus-level lockstep scenarios against
the mutant's firmware (HIL_FIRMWARE) with `-x`, the scenarios that killed most mutants so far
first. Each mutant's result is written as soon as it is known (build/mutate/mutants/ID), so a
run stopped and started again goes on where it was.

A hang is a kill only against the unmutated firmware's own time. Unit tests: each gets
HANG_FACTOR times the slowest test of the baseline ctest run on this machine plus a margin. In
the scenarios a firmware that hangs is a failure of the lockstep HangGuard (asleep with TPDOs due,
or its CPU spent without an answer, where the unmutated firmware answers within milliseconds of
CPU): a kill. The whole scenario run's bound (HANG_FACTOR times the recorded durations plus a
margin) is only a guard: a loaded host made a survivor overrun it, so reaching it is no verdict
and the mutant's scenarios count as not run. A scenario that fails because the host was starved
(HostStarvedError) is no kill either: it is run again once, and counted as not run if it starves
again.

Mutants reviewed as equivalent (they cannot change what the firmware does) are listed with a
reason in tools/mutants-equivalent.toml and are not counted.
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import io
import json
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import time
import tomllib
import xml.etree.ElementTree as ET
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass
from fnmatch import fnmatch
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import mutation_report as report
import scenario_shards

REPO = Path(__file__).resolve().parent.parent
PRODUCT = ("firmware/**/*.cpp", "firmware/**/*.hpp")
NOT_PRODUCT = (
    "*Test.cpp",
    "*TestSupport.*",
    "firmware/bench/*",
    "firmware/canopen/fuzz/*",
    "firmware/joint/testing/*",
    "firmware/canopen/MemoryPort.hpp",  # the engine's tests' CanPort double
    "firmware/canopen/BlockCrcReference.hpp",  # the tests' reference CRC
    "firmware/platform/linux/ParameterStoreCrash*",  # the crash test's child process
    "firmware/core/PortableCheck.cpp",  # a compile-only check
    # The Cortex-M platform, and the node's views of the joint only it uses so far: built and
    # tested by the cross build (make cortex-m), not the host build a mutant is tested in.
    "firmware/platform/cortex-m/*",
    "firmware/platform/common/*",
)
RULES = ("universal.rules", "cpp.rules", "c_like.rules")
"""universalmutator's rule files for C++, as its own `mutate FILE cpp` picks them."""
NOT_MUTATED = (
    r"^\s*#",  # preprocessor: includes, guards
    r"^\s*//",  # comments
    r"static_assert",  # compile-time checks: a mutant either does not build or changes nothing
    r"\bassert\s*\(",  # NDEBUG in the release-like test build
)
EQUIVALENTS = REPO / "tools" / "mutants-equivalent.toml"
DEFAULT_OUT = REPO / "build" / "mutate"
FIRMWARE_BINARY = "bin/joint-firmware"
CMAKE_ARGS = ("-DCMAKE_BUILD_TYPE=RelWithDebInfo", "-DHIL_SANITIZE=ON", "-DHIL_TESTS=ON")
"""The configuration of `make build`: what `make test` runs."""
SOURCES = ("CMakeLists.txt", "firmware", "protocol")
"""What the build needs of the checkout (copied into the workspace)."""
HANG_FACTOR = 3
HANG_MARGIN_S = 60.0
SCENARIO_WORKERS = 2


@dataclass(frozen=True)
class Mutant:
    id: str
    path: str  # relative to the source root
    line: int  # 1-based
    original: str
    replacement: str
    rule: str

    def apply(self, text: str) -> str:
        lines = text.splitlines(keepends=True)
        if lines[self.line - 1] != self.original:
            raise ValueError(f"{self.path}:{self.line} is no longer {self.original!r}")
        lines[self.line - 1] = self.replacement
        return "".join(lines)


# --- Which mutants ---------------------------------------------------------------------------
def product_files(
    root: Path, product: Sequence[str] = PRODUCT, not_product: Sequence[str] = NOT_PRODUCT
) -> list[str]:
    found = {str(p.relative_to(root)) for pattern in product for p in root.glob(pattern) if p.is_file()}
    return sorted(
        f
        for f in found
        if not any(fnmatch(f, pattern) or fnmatch(Path(f).name, pattern) for pattern in not_product)
    )


def mutants_of(root: Path, path: str) -> list[Mutant]:
    """Every mutant of one file by universalmutator's C++ rules, in line order. The id is made
    of the file, the line's text, the replacement and which such occurrence it is: it survives
    edits elsewhere in the file (the equivalents list names mutants by it)."""
    from universalmutator import mutator

    source = (root / path).read_text().splitlines(keepends=True)
    with contextlib.redirect_stdout(io.StringIO()):  # it prints its progress
        found = mutator.mutants_regexp(
            source, ruleFiles=list(RULES), ignorePatterns=list(NOT_MUTATED), ignoreStringOnly=True
        )
    seen: Counter[tuple[str, str]] = Counter()
    result = []
    for line, replacement, rule_used, _ in sorted(found, key=lambda m: (m[0], m[1])):
        original = source[line - 1]
        if code_of(original) == code_of(replacement):
            continue  # a statement appended behind a // comment: no change at all
        if changes_digits_of_a_name(original, replacement):
            continue  # uint32_t -> uint(32+1)_t, 0x3F -> (0+1)x3F: never compiles
        seen[(original, replacement)] += 1
        key = f"{path}\0{original}\0{replacement}\0{seen[(original, replacement)]}"
        digest = hashlib.sha1(key.encode()).hexdigest()[:8]
        rule = rule_used[0].strip() if isinstance(rule_used, tuple) else str(rule_used)
        result.append(Mutant(f"{Path(path).stem}-{digest}", path, line, original, replacement, rule))
    return result


_INTEGER_LITERAL = re.compile(r"(?<![\w.'])\d+(?:[uU]?[lL]{0,2}|[lL]{1,2}[uU]?)(?![\w.'])")


def changes_digits_of_a_name(original: str, replacement: str) -> bool:
    """Whether the first change is to digits that are not a whole integer literal: part of a
    name (uint32_t), of a hex or float literal (0x3F, 1.0F). universalmutator's literal rule
    matches those too, and such a mutant never compiles: not generated, so as not to spend a
    build on it."""
    start = next((i for i, (a, b) in enumerate(zip(original, replacement, strict=False)) if a != b), None)
    if start is None or not (original[start].isdigit() or (start and original[start - 1].isdigit())):
        return False
    while start and original[start - 1].isdigit():
        start -= 1
    return _INTEGER_LITERAL.match(original, start) is None


def code_of(line: str) -> str:
    """A line's code without its // comment, whitespace normalised."""
    return " ".join(line.split("//", 1)[0].split())


def all_mutants(root: Path, files: Iterable[str]) -> list[Mutant]:
    return [m for path in files for m in mutants_of(root, path)]


def sample(mutants: Sequence[Mutant], count: int, seed: int) -> list[Mutant]:
    """A seeded sample of `count` (all of them if fewer), in the order drawn."""
    return random.Random(seed).sample(list(mutants), min(count, len(mutants)))


def shard_of(mutants: Sequence[Mutant], shard: scenario_shards.Shard | None) -> list[Mutant]:
    return list(mutants) if shard is None else list(mutants[shard.index - 1 :: shard.count])


def load_equivalents(path: Path = EQUIVALENTS) -> dict[str, str]:
    """Reviewed equivalent mutants: id -> reason."""
    if not path.exists():
        return {}
    entries = tomllib.loads(path.read_text()).get("equivalent", [])
    return {entry["id"]: entry["reason"] for entry in entries}


# --- The workspace: a copy of the sources and its build tree ---------------------------------
@dataclass(frozen=True)
class Workspace:
    out: Path
    source_root: Path
    sources: tuple[str, ...] = SOURCES
    cmake_args: tuple[str, ...] = CMAKE_ARGS

    @property
    def src(self) -> Path:
        return self.out / "src"

    @property
    def build(self) -> Path:
        return self.out / "build"

    def mutant_dir(self, mutant: Mutant) -> Path:
        return self.out / "mutants" / mutant.id

    def sync(self) -> None:
        """Copy what changed of the sources (content compared, so untouched files keep their
        times and the build stays incremental)."""
        for name in self.sources:
            origin = self.source_root / name
            for file in [origin] if origin.is_file() else sorted(p for p in origin.rglob("*") if p.is_file()):
                if "__pycache__" in file.parts:
                    continue
                target = self.src / file.relative_to(self.source_root)
                if target.exists() and target.read_bytes() == file.read_bytes():
                    continue
                target.parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(file, target)

    def configure(self) -> None:
        if (self.build / "build.ninja").exists():
            return
        python = REPO / ".venv" / "bin" / "python"
        run_checked(
            [
                "cmake",
                "-S",
                str(self.src),
                "-B",
                str(self.build),
                "-G",
                "Ninja",
                f"-DHIL_PYTHON={python}",
                *self.cmake_args,
            ],
            "configure the mutation build",
        )

    def compile(self, jobs: int) -> subprocess.CompletedProcess[str]:
        return run_group(["cmake", "--build", str(self.build), "-j", str(jobs)])


def run_group(argv: Sequence[str], timeout_s: float | None = None) -> subprocess.CompletedProcess[str]:
    """Run `argv` in a process group of its own, output captured. On Ctrl-C, SIGTERM or the
    timeout the whole group gets SIGINT first, so that ninja deletes what it was writing (a
    compiler killed alone leaves a half-written object file that looks up to date), then
    SIGKILL. subprocess.run would kill only its child and leave the build's processes running."""
    process = subprocess.Popen(
        argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True
    )
    try:
        output, _ = process.communicate(timeout=timeout_s)
    except BaseException:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGINT)
        try:
            process.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(process.pid, signal.SIGKILL)
            process.communicate()
        raise
    return subprocess.CompletedProcess(list(argv), process.returncode, output, "")


def run_checked(argv: Sequence[str], what: str) -> None:
    result = subprocess.run(argv, capture_output=True, text=True, check=False)
    if result.returncode != 0:
        tail = "\n".join((result.stdout + result.stderr).splitlines()[-30:])
        raise SystemExit(f"mutate: cannot {what} ({' '.join(argv[:3])} ...):\n{tail}")


@contextlib.contextmanager
def mutated(workspace: Workspace, mutant: Mutant):
    """The mutant's file changed in the workspace for the body; the original back afterwards,
    whatever happens (Ctrl-C included). The body sets `untouched_outputs` when the build failed
    before writing anything of the mutant: a .cpp file's one object file was not rewritten (the
    compiler writes none on an error), so the original gets its old time back and is not
    compiled again for the next mutant. Never for a header: other translation units that
    include it may have compiled the mutant before the error."""
    path = workspace.src / mutant.path
    original = path.read_text()
    before = path.stat()
    path.write_text(mutant.apply(original))
    state = {"untouched_outputs": False}
    try:
        yield state
    finally:
        path.write_text(original)
        if state["untouched_outputs"] and path.suffix == ".cpp":
            os.utime(path, ns=(before.st_atime_ns, before.st_mtime_ns))


# --- The unit-test layer ----------------------------------------------------------------------
def ctest(build: Path, jobs: int, timeout_s: float, junit: Path) -> tuple[list[str], str | None, float]:
    """Run every C++ unit test: (the tests that failed, why the run timed out or None, seconds)."""
    started = time.monotonic()
    argv = [
        "ctest",
        "--test-dir",
        str(build),
        "-j",
        str(jobs),
        "--timeout",
        f"{timeout_s:.0f}",
        "--output-junit",
        str(junit),
    ]
    result = run_group(argv)
    seconds = time.monotonic() - started
    failed, timed_out = [], []
    if junit.exists():
        for case in ET.parse(junit).getroot().iter("testcase"):
            if case.get("status") == "fail" or case.find("failure") is not None:
                failed.append(case.get("name", "?"))
    for line in result.stdout.splitlines():
        if "***Timeout" in line:
            timed_out.append(line.split(":", 1)[-1].split("*")[0].strip())
    if result.returncode < 0:  # ctest itself killed by a signal: no verdict on the mutant
        raise KeyboardInterrupt(f"ctest stopped by signal {-result.returncode}")
    if result.returncode != 0 and not failed:
        failed.append(f"ctest exit {result.returncode}")
    timeout = f"unit tests past {timeout_s:.0f} s: {', '.join(timed_out)}" if timed_out else None
    return [f for f in failed if not any(t and t in f for t in timed_out)], timeout, seconds


def baseline_unit_timeout(build: Path, jobs: int, out: Path) -> float:
    """The unit tests on the unmutated build must pass; each mutant's tests then get
    HANG_FACTOR times the slowest test's time here, plus the margin."""
    junit = out / "baseline-ctest.xml"
    failed, _, seconds = ctest(build, jobs, 1800, junit)
    if failed:
        raise SystemExit(f"mutate: the unit tests fail on the unmutated firmware: {', '.join(failed[:5])}")
    slowest = max(
        (float(c.get("time", 0)) for c in ET.parse(junit).getroot().iter("testcase")), default=seconds
    )
    return HANG_FACTOR * slowest + HANG_MARGIN_S


# --- The scenario layer (inside the VM) -------------------------------------------------------
def collect_scenarios(out: Path) -> list[str]:
    """The lockstep scenarios' node ids (collected natively; the VM runs them)."""
    argv = [sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider"]
    argv += scenario_shards.selection_args("lockstep")
    result = subprocess.run(argv, cwd=REPO, capture_output=True, text=True, check=False)
    ids = [line for line in result.stdout.splitlines() if "::" in line]
    if not ids:
        raise SystemExit(
            f"mutate: no lockstep scenario collected:\n{result.stdout[-2000:]}{result.stderr[-2000:]}"
        )
    report.write_json(out / "scenarios.json", ids)
    return ids


def scenario_order(ids: Sequence[str], kills: Counter[str], durations: dict[str, float]) -> list[str]:
    """Those that killed most mutants so far first, then the short ones."""
    average = sum(durations.values()) / len(durations) if durations else 1.0
    return sorted(ids, key=lambda t: (-kills[t], durations.get(t, average), t))


def run_scenarios(
    firmware: Path, ids: Sequence[str], durations: dict[str, float], out: Path
) -> tuple[list[str], str | None, bool, float]:
    """One mutant's scenarios, -x: (the scenarios that failed, why the run timed out, whether a
    failure was only the host starving, seconds)."""
    expected = sum(durations.get(t, 10.0) for t in ids) / SCENARIO_WORKERS
    timeout_s = HANG_FACTOR * expected + HANG_MARGIN_S
    junit = out / "scenarios.xml"
    junit.unlink(missing_ok=True)
    argv = [
        sys.executable,
        "-m",
        "pytest",
        *ids,
        "-x",
        "-q",
        "-n",
        str(SCENARIO_WORKERS),
        "-p",
        "no:cacheprovider",
        f"--junitxml={junit}",
    ]
    env = dict(
        os.environ,
        HIL_FIRMWARE=str(firmware),
        HIL_OUT_DIR=str(out / "scenario-out"),
        HIL_SCENARIO_ORDER="given",
    )
    started = time.monotonic()
    with open(out / "scenarios.log", "w") as log:
        process = subprocess.Popen(
            argv, cwd=REPO, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True
        )
        try:
            process.wait(timeout_s)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
            seconds = time.monotonic() - started
            why = (
                f"scenarios past {timeout_s:.0f} s ({HANG_FACTOR}x the unmutated firmware's "
                f"{expected:.0f} s + {HANG_MARGIN_S:.0f} s)"
            )
            return [], why, False, seconds
        except BaseException:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
            raise
    seconds = time.monotonic() - started
    failed, starved = [], []
    if junit.exists():
        for case in ET.parse(junit).getroot().iter("testcase"):
            problem = case.find("failure")
            if problem is None:
                problem = case.find("error")
            if problem is None:
                continue
            name = f"{case.get('classname', '').replace('.', '/')}.py::{case.get('name')}"
            text = (problem.get("message") or "") + (problem.text or "")
            (starved if "HostStarvedError" in text else failed).append(name)
    if process.returncode not in (0, 1) and not failed and not starved:
        failed.append(f"pytest exit {process.returncode}")
    return failed, None, bool(starved) and not failed, seconds


def scenarios_command(out: Path) -> int:
    """Inside the VM: the scenario layer for every built mutant of the run's plan that has none."""
    plan = json.loads((out / "plan.json").read_text())
    ids = json.loads((out / "scenarios.json").read_text())
    durations = json.loads((REPO / scenario_shards.DURATIONS).read_text())
    kills_path = out / "kills.json"
    kills: Counter[str] = Counter(json.loads(kills_path.read_text()) if kills_path.exists() else {})
    equivalent = load_equivalents()
    todo = [m for m in plan["mutants"] if m not in equivalent and _needs_scenarios(out / "mutants" / m)]
    missing = [m for m in todo if not (out / "mutants" / m / Path(FIRMWARE_BINARY).name).exists()]
    if missing:  # never a kill: a scenario against no firmware fails whatever the mutant does
        print(f"mutate: no firmware kept for {', '.join(missing)}: run `run` again to build them", flush=True)
        todo = [m for m in todo if m not in missing]
    for number, mutant_id in enumerate(todo, 1):
        folder = out / "mutants" / mutant_id
        result = json.loads((folder / "result.json").read_text())
        order = scenario_order(ids, kills, durations)
        for attempt in (1, 2):
            failed, timeout, starved, seconds = run_scenarios(
                folder / "joint-firmware", order, durations, folder
            )
            if not starved:
                break
            print(f"mutate: {mutant_id}: the host starved the scenarios (attempt {attempt})", flush=True)
        if not failed:
            # A survivor's scenarios wrote a trace each (hundreds of MB a mutant): not kept.
            shutil.rmtree(folder / "scenario-out", ignore_errors=True)
        if starved or timeout:
            # No verdict: the run's bound comes from a quiet machine's durations, and a loaded
            # host (this run's own builds) made a survivor overrun it. A firmware that hangs is
            # a kill through the HangGuard (idle with TPDOs due, or its CPU spent unanswered).
            result["scenarios"] = None
            result["scenarios_not_run"] = timeout or "the host starved the scenarios twice"
        else:
            result["scenarios"] = {"killed_by": failed, "timeout": timeout}
            result.setdefault("seconds", {})["scenarios"] = round(seconds, 1)
            kills.update(failed)
            report.write_json(kills_path, dict(kills))
        report.write_json(folder / "result.json", result)
        verdict = "killed by " + failed[0] if failed else (timeout or "survived")
        print(f"mutate: scenarios {number}/{len(todo)} {mutant_id}: {verdict} ({seconds:.0f} s)", flush=True)
    return 0


def _needs_scenarios(folder: Path) -> bool:
    result_path = folder / "result.json"
    if not result_path.exists():
        return False
    result = json.loads(result_path.read_text())
    return result.get("compiled", False) and result.get("scenarios") is None  # none yet, or starved


# --- The run ----------------------------------------------------------------------------------
def source_digest(root: Path, path: str) -> str:
    return hashlib.sha1((root / path).read_bytes()).hexdigest()


def build_and_unit(
    workspace: Workspace, mutants: Sequence[Mutant], jobs: int, copy_binary: str | None
) -> None:
    """Build each mutant and run the unit tests on it (results kept per mutant)."""
    workspace.sync()
    workspace.configure()
    print("mutate: building the unmutated firmware (baseline)", flush=True)
    baseline = workspace.compile(jobs)
    if baseline.returncode != 0:
        raise SystemExit(f"mutate: the unmutated sources do not build:\n{baseline.stdout[-3000:]}")
    unit_timeout = baseline_unit_timeout(workspace.build, jobs, workspace.out)
    if copy_binary is not None and not (workspace.build / copy_binary).exists():
        copy_binary = None  # a tree without the firmware (the tool's own test): unit tests only
    for number, mutant in enumerate(mutants, 1):
        folder = workspace.mutant_dir(mutant)
        result_path = folder / "result.json"
        digest = source_digest(workspace.source_root, mutant.path)
        known = json.loads(result_path.read_text()) if result_path.exists() else {}
        if known.get("source_sha1") == digest:
            binary = folder / Path(copy_binary).name if copy_binary else None
            if binary is None or not known.get("compiled") or binary.exists():
                continue  # done in an earlier run, on the same source
            with mutated(workspace, mutant):  # its unit results stand; its firmware is needed again
                if workspace.compile(jobs).returncode == 0:
                    shutil.copy2(workspace.build / copy_binary, binary)
            continue
        shutil.rmtree(folder, ignore_errors=True)
        folder.mkdir(parents=True)
        result: dict[str, object] = {**asdict(mutant), "source_sha1": digest}
        started = time.monotonic()
        with mutated(workspace, mutant) as state:
            built = workspace.compile(jobs)
            build_s = time.monotonic() - started
            if built.returncode != 0:
                state["untouched_outputs"] = True
                result.update(compiled=False, seconds={"build": round(build_s, 1)})
                print(f"mutate: {number}/{len(mutants)} {mutant.id}: does not compile, dropped", flush=True)
            else:
                if copy_binary is not None and (workspace.build / copy_binary).exists():
                    shutil.copy2(workspace.build / copy_binary, folder / Path(copy_binary).name)
                failed, timeout, unit_s = ctest(workspace.build, jobs, unit_timeout, folder / "ctest.xml")
                result.update(
                    compiled=True,
                    unit={"killed_by": failed, "timeout": timeout},
                    seconds={"build": round(build_s, 1), "unit": round(unit_s, 1)},
                )
                verdict = f"killed by {len(failed)} unit tests" if failed else (timeout or "unit tests pass")
                print(
                    f"mutate: {number}/{len(mutants)} {mutant.id}: {verdict} "
                    f"({build_s:.0f} s build, {unit_s:.0f} s tests)",
                    flush=True,
                )
        report.write_json(result_path, result)


def outcome_of(result: dict, equivalents: dict[str, str]) -> report.Outcome:
    unit = result.get("unit")
    scenarios = result.get("scenarios")
    return report.Outcome(
        id=result["id"],
        path=result["path"],
        line=result["line"],
        original=result["original"],
        replacement=result["replacement"],
        rule=result["rule"],
        compiled=result.get("compiled", False),
        unit_killed_by=unit["killed_by"] if unit else None,
        unit_timeout=unit["timeout"] if unit else None,
        scenario_killed_by=scenarios["killed_by"] if scenarios else None,
        scenario_timeout=scenarios["timeout"] if scenarios else None,
        equivalent=equivalents.get(result["id"]),
        seconds=result.get("seconds", {}),
    )


def write_report(
    out: Path, name: str, mutants: Sequence[Mutant], source_root: Path, config: dict
) -> list[report.Outcome]:
    equivalents = load_equivalents()
    outcomes = []
    for mutant in mutants:
        path = out / "mutants" / mutant.id / "result.json"
        if path.exists():
            outcomes.append(outcome_of(json.loads(path.read_text()), equivalents))
    sources = {o.path: (source_root / o.path).read_text() for o in outcomes}
    report.write_json(out / f"{name}.json", report.to_stryker(outcomes, sources, config))
    text = report.summary(outcomes, f"mutation testing: {config['description']}")
    report.write_atomically(out / f"{name}.txt", text)
    print(text)
    print(
        f"mutate: report {out / (name + '.json')} (mutation-testing-report-schema), "
        f"summary {out / (name + '.txt')}"
    )
    return outcomes


@dataclass(frozen=True)
class Selection:
    """The mutants a `run`, `report` or `list` call is about, and how its report names them."""

    mutants: list[Mutant]
    source_root: Path
    description: str
    report_name: str
    config: dict[str, object]


def select(args: argparse.Namespace) -> Selection:
    """The seeded sample (or its shard) of every mutant of the product files; `--mutant ID`s
    instead, where the command has them."""
    shard = scenario_shards.parse_shard(args.shard) if args.shard else None
    source_root = Path(args.source).resolve()
    files = product_files(source_root, args.product or PRODUCT)
    everything = all_mutants(source_root, files)
    if getattr(args, "mutant", None):
        by_id = {m.id: m for m in everything}
        unknown = [i for i in args.mutant if i not in by_id]
        if unknown:
            raise ValueError(
                f"no such mutant: {', '.join(unknown)} (`tools/mutate.py list` shows a sample's ids)"
            )
        chosen = [by_id[i] for i in args.mutant]
        description = f"{len(chosen)} mutants chosen by id"
    else:
        chosen = shard_of(sample(everything, args.mutants, args.seed), shard)
        where = f", shard {shard}" if shard else ""
        description = f"{len(chosen)} of {len(everything)} mutants (seed {args.seed}{where})"
    config = {
        "description": description,
        "seed": args.seed,
        "mutants": args.mutants,
        "shard": str(shard) if shard else None,
        "project_root": str(source_root),
    }
    name = f"report-shard-{shard.index}-of-{shard.count}" if shard else "report"
    return Selection(chosen, source_root, f"{description} of {len(files)} product files", name, config)


def run_command(args: argparse.Namespace) -> int:
    chosen = select(args)
    out = Path(args.out).resolve()
    print(f"mutate: {chosen.description}", flush=True)
    out.mkdir(parents=True, exist_ok=True)
    report.write_json(out / "plan.json", {"mutants": [m.id for m in chosen.mutants]})
    workspace = Workspace(out, chosen.source_root, tuple(args.sources), tuple(args.cmake_arg or CMAKE_ARGS))
    build_and_unit(workspace, chosen.mutants, args.jobs, FIRMWARE_BINARY)
    if not args.no_scenarios:
        collect_scenarios(out)
        print(
            "mutate: bus-level scenarios of every built mutant, in one micro-VM (tools/with-vcan)", flush=True
        )
        vm = subprocess.run(
            [
                str(REPO / "tools" / "with-vcan"),
                "--no-uml",  # the mutants are ASan builds, which user-mode Linux cannot start
                "--",
                sys.executable,
                str(Path(__file__).resolve()),
                "scenarios",
                "--out",
                str(out),
            ],
            cwd=REPO,
            check=False,
        )
        if vm.returncode != 0:
            print(
                f"mutate: the scenario stage ended with exit {vm.returncode}; the report shows what ran",
                file=sys.stderr,
            )
    write_report(out, chosen.report_name, chosen.mutants, chosen.source_root, chosen.config)
    return 0


def one_line(code: str) -> str:
    return " ".join(code.split("\n")).strip()


def report_command(args: argparse.Namespace) -> int:
    """The report of a sample from the results kept so far, nothing built or run."""
    chosen = select(args)
    write_report(
        Path(args.out).resolve(), chosen.report_name, chosen.mutants, chosen.source_root, chosen.config
    )
    return 0


def list_command(args: argparse.Namespace) -> int:
    for mutant in select(args).mutants:
        print(
            f"{mutant.id}  {mutant.path}:{mutant.line}  "
            f"{one_line(mutant.original)}  ->  {one_line(mutant.replacement)}"
        )
    return 0


def merge_command(args: argparse.Namespace) -> int:
    reports = [json.loads(Path(p).read_text()) for p in args.reports]
    merged = report.merge(reports)
    out = Path(args.out)
    report.write_json(out / "report.json", merged)
    outcomes = report.from_stryker(merged)
    text = report.summary(outcomes, f"mutation testing: {len(reports)} shards merged")
    report.write_atomically(out / "report.txt", text)
    print(text)
    return 0


def _interrupted(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="tools/mutate.py", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    helps = {
        "run": "run a sample",
        "list": "print a sample, build nothing",
        "report": "a sample's report from the results so far",
    }
    for name in ("run", "list", "report"):
        p = sub.add_parser(name, help=helps[name])
        p.add_argument("--mutants", type=int, default=40, help="how many mutants to sample (default 40)")
        p.add_argument("--seed", type=int, default=1, help="the sample's seed (default 1)")
        p.add_argument("--shard", help="K/N: the K-th of N shards of the sample")
        p.add_argument("--source", default=str(REPO), help=argparse.SUPPRESS)
        p.add_argument("--product", action="append", help=argparse.SUPPRESS)
    sub.choices["report"].add_argument(
        "--out", default=str(DEFAULT_OUT), help="the run's folder (default build/mutate)"
    )
    run = sub.choices["run"]
    run.add_argument("--out", default=str(DEFAULT_OUT), help="workspace and report (default build/mutate)")
    run.add_argument("--jobs", type=int, default=os.cpu_count() or 2, help="build and ctest parallelism")
    run.add_argument("--no-scenarios", action="store_true", help="unit tests only (no VM)")
    run.add_argument(
        "--mutant", action="append", metavar="ID", help="run this mutant (repeatable), not a sample"
    )
    run.add_argument("--sources", nargs="+", default=list(SOURCES), help=argparse.SUPPRESS)
    run.add_argument("--cmake-arg", action="append", help=argparse.SUPPRESS)
    merge = sub.add_parser("merge", help="merge shards' reports")
    merge.add_argument("reports", nargs="+")
    merge.add_argument("--out", required=True)
    scen = sub.add_parser("scenarios", help="(inside tools/with-vcan) the scenario layer of a run")
    scen.add_argument("--out", default=str(DEFAULT_OUT))
    args = parser.parse_args(argv)
    # SIGTERM as Ctrl-C, and Ctrl-C even where the shell started this in the background with
    # SIGINT ignored: the mutated file goes back and the build's processes are stopped first.
    signal.signal(signal.SIGTERM, _interrupted)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        if args.command == "run":
            return run_command(args)
        if args.command == "list":
            return list_command(args)
        if args.command == "report":
            return report_command(args)
        if args.command == "merge":
            return merge_command(args)
        return scenarios_command(Path(args.out))
    except (ValueError, OSError, KeyError) as error:  # a bad SHARD, a missing or foreign report
        print(f"mutate: {type(error).__name__}: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("mutate: stopped; the results so far are kept (run again to go on)", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
