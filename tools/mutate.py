"""Mutation testing of the firmware: how many small, realistic changes to its product code do the
tests reject? `make mutate` runs it; the verdict is in tools/mutation_report.py.

    tools/mutate.py run [--mutants N] [--seed S] [--shard K/N] [--out DIR] [--no-scenarios]
                        [--no-coverage] [--mutant ID ...]
    tools/mutate.py list [--mutants N] [--seed S] [--shard K/N]      the sample, nothing built
    tools/mutate.py report [--mutants N] [--seed S] [--shard K/N]    the report from the results so far
    tools/mutate.py merge REPORT... --out DIR                         shards' reports as one
    tools/mutate.py keep [--out DIR]            its finished verdicts into tools/mutants-judged.json
    tools/mutate.py scenarios|coverage --out DIR                      (inside tools/with-vcan)

The mutants (tools/mutate_mutants.py): universalmutator's C++ rules and the realistic operators
of tools/mutate_operators.py, applied to one line of one product file at a time (firmware/
without its tests, benchmarks, fuzzers and test doubles: NOT_PRODUCT), without those that cannot
compile. The sample (tools/mutate_sampling.py): N counted mutants (compiled, not listed as
equivalent) stratified over the product files that the host build compiles (another target's
platform, e.g. the bare-metal qemu-virt firmware, is built and tested by its own target and not
sampled; the report lists them), seeded (SEED); a shard K/N takes its part of
every file's candidates and share, so the shards of one sample add up to it and `merge` puts
their reports together.

Each candidate, in a copy of the sources (build/mutate/src: the checkout is never touched, and
Ctrl-C leaves nothing half-mutated), has its translation unit syntax-checked, then is built
incrementally in the test configuration (ASan + UBSan); one that does not compile is dropped,
counted, and replaced by its file's next. Then the C++ unit tests that execute its line (ctest;
tools/mutate_coverage.py records which once per source state), then, in one user-mode Linux VM
for the whole sample, the lockstep scenarios that execute its line against the mutant's release
firmware (HIL_FIRMWARE; built in a tree of its own, tools/mutate_workspace.py), as make test's
lockstep stage runs them, tools/mutate_scenarios.py. Each mutant's result is written as soon as it is
known (build/mutate/mutants/ID), so a run stopped and started again goes on where it was; `keep`
adds the finished ones to tools/mutants-judged.json (tools/mutate_kept.py), from which a run in a
fresh checkout starts each mutant whose file has not changed.

A hang is a kill only against the unmutated firmware's own time. Unit tests: each gets
HANG_FACTOR times the slowest test of the baseline ctest run on this machine plus a margin; the
scenarios' rule is in tools/mutate_scenarios.py.

Mutants reviewed as equivalent (they cannot change what the firmware does) are listed with a
reason in tools/mutants-equivalent.toml and are not counted.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import mutate_coverage as coverage
import mutate_kept as kept_verdicts
import mutate_sampling as sampling
import mutation_report as report
import scenario_shards
from mutate_coverage import COVERAGE_CMAKE_ARGS
from mutate_mutants import (  # noqa: F401 (the tool's names, as its tests use them)
    EQUIVALENTS,
    NOT_PRODUCT,
    PRODUCT,
    REPO,
    Mutant,
    all_mutants,
    compiled_by,
    load_equivalents,
    mutants_of,
    product_files,
    source_digest,
)
from mutate_scenarios import (
    FIRMWARE_BINARIES,
    HANG_FACTOR,
    HANG_MARGIN_S,
    SCENARIO_FIRMWARE,
    collect_scenarios,
    coverage_command,
    scenarios_command,
)
from mutate_workspace import (
    CMAKE_ARGS,
    SOURCES,
    Workspace,
    keep_scenario_firmware,
    mutated,
    run_group,
    scenario_tree_of,
    stop_group,
    syntax_check,
)

DEFAULT_OUT = REPO / "build" / "mutate"


# --- The unit-test layer ----------------------------------------------------------------------
def ctest(
    build: Path, jobs: int, timeout_s: float, junit: Path, names: Sequence[str] | None = None
) -> tuple[list[str], str | None, float]:
    """Run the C++ unit tests (those named, else all): (the tests that failed, why the run timed
    out or None, seconds)."""
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
        *(["-R", coverage.ctest_regex(names)] if names is not None else []),
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


# --- The run ----------------------------------------------------------------------------------
def ensure_unit_coverage(workspace: Workspace, jobs: int) -> coverage.Coverage | None:
    """The coverage record of the unit tests for the workspace's sources: built and recorded
    when the sources changed (a build tree of its own), else read back."""
    folder = workspace.out / "coverage"
    record_path = folder / "coverage.json"
    digest = coverage.sources_digest(workspace.src, workspace.sources)
    if record_path.exists():
        known = coverage.Coverage.from_json(json.loads(record_path.read_text()))
        if known.digest == digest:
            return known
    tree = Workspace(
        workspace.out, workspace.source_root, workspace.sources, COVERAGE_CMAKE_ARGS, "coverage/build"
    )
    tree.configure()
    print("mutate: building the unmutated sources with --coverage (once per source state)", flush=True)
    started = time.monotonic()
    if tree.compile(jobs).returncode != 0:
        print("mutate: the coverage build failed: every test runs on every mutant", flush=True)
        return None
    shutil.rmtree(folder / "unit-counters", ignore_errors=True)
    record = coverage.record_unit_tests(tree.build, tree.src, folder / "unit-counters", digest, jobs)
    report.write_json(record_path, record.to_json())
    print(f"mutate: unit-test coverage recorded ({time.monotonic() - started:.0f} s)", flush=True)
    return record


def ensure_scenario_coverage(out: Path) -> None:
    """The scenarios' part of the coverage record (a user-mode Linux VM: the coverage build has
    no sanitizer), recorded once per source state."""
    record_path = out / "coverage" / "coverage.json"
    if not record_path.exists():
        return
    record = coverage.Coverage.from_json(json.loads(record_path.read_text()))
    if any(t.startswith(coverage.SCENARIO) for t in record.tests):
        return
    print("mutate: recording which lines each lockstep scenario executes (once per source state)", flush=True)
    code = run_in_vm(out, "coverage", uml=True)
    if code != 0:  # stopped: no record, so that the next run records it again
        print(f"mutate: the scenarios' coverage run ended with exit {code}: every scenario runs", flush=True)
        return
    ids = json.loads((out / "scenarios.json").read_text())["ids"]
    scenarios = coverage.record_scenarios(
        ids, out / "coverage" / "scenario-counters", out / "coverage" / "build", out / "src", record.digest
    )
    report.write_json(record_path, coverage.merge([record, scenarios]).to_json())


def counted(out: Path, mutant: Mutant, equivalents: dict[str, str]) -> bool:
    """Whether a mutant tried counts: it compiled and is not listed as equivalent."""
    path = out / "mutants" / mutant.id / "result.json"
    return (
        mutant.id not in equivalents and path.exists() and json.loads(path.read_text()).get("compiled", False)
    )


def prepare(workspace: Workspace, jobs: int, scenario_tree: Workspace | None = None) -> None:
    """The workspace's sources up to date and the unmutated firmware built (the baseline), in the
    test configuration and, when scenarios run, the scenarios' firmware in `scenario_tree`."""
    workspace.sync()
    workspace.configure()
    print("mutate: building the unmutated firmware (baseline)", flush=True)
    baseline = workspace.compile(jobs)
    if baseline.returncode != 0:
        raise SystemExit(f"mutate: the unmutated sources do not build:\n{baseline.stdout[-3000:]}")
    if scenario_tree is not None:
        scenario_tree.configure()
        built = scenario_tree.compile(jobs, scenario_tree.known(FIRMWARE_BINARIES))
        if built.returncode != 0:
            raise SystemExit(f"mutate: the scenarios' firmware does not build:\n{built.stdout[-3000:]}")


def build_and_unit(
    workspace: Workspace,
    candidates: Iterable[Mutant],
    jobs: int,
    scenario_tree: Workspace | None = None,
    use_coverage: bool = True,
    again: bool = False,
) -> list[Mutant]:
    """Build each candidate and run the unit tests that execute its line on it (results kept
    per mutant); returns the mutants tried (the listed equivalents are skipped, not built).
    With a `scenario_tree`, each mutant's firmware for the scenarios is built there and kept in
    its folder. The workspace is prepared (`prepare`) first."""
    judged_at = kept_verdicts.head_commit(workspace.source_root)
    unit_timeout = baseline_unit_timeout(workspace.build, jobs, workspace.out)
    record = ensure_unit_coverage(workspace, jobs) if use_coverage else None
    unit_groups = coverage.unit_tests_by_executable(workspace.build) if record else {}
    # Without scenarios the firmware is still built: it is what "compiles" means for a mutant
    # no unit test executes.
    binaries = [] if scenario_tree else [b for b in FIRMWARE_BINARIES if (workspace.build / b).exists()]
    scenario_binaries = scenario_tree.known(FIRMWARE_BINARIES) if scenario_tree else []
    equivalents = load_equivalents()
    tried: list[Mutant] = []
    for mutant in candidates:
        if mutant.id in equivalents:
            continue
        tried.append(mutant)
        number = len(tried)
        folder = workspace.mutant_dir(mutant)
        result_path = folder / "result.json"
        digest = source_digest(workspace.source_root, mutant.path)
        known = json.loads(result_path.read_text()) if result_path.exists() and not again else {}
        if known.get("source_sha1") == digest:
            kept = [folder / SCENARIO_FIRMWARE / Path(b).name for b in scenario_binaries]
            judged = known.get("scenarios") is not None  # its whole verdict is known (or kept)
            if scenario_tree is None or not known.get("compiled") or judged or all(k.exists() for k in kept):
                continue  # done in an earlier run, on the same source
            with mutated(workspace, mutant):  # its unit results stand; its firmware is needed again
                if scenario_tree.compile(jobs, scenario_binaries).returncode == 0:
                    keep_scenario_firmware(scenario_tree, scenario_binaries, folder)
            continue
        shutil.rmtree(folder, ignore_errors=True)
        folder.mkdir(parents=True)
        result: dict[str, object] = {**asdict(mutant), "source_sha1": digest, "judged_at": judged_at}
        started = time.monotonic()
        executables = record.covering(mutant.path, mutant.line, coverage.UNIT) if record else None
        targets = needed_targets(workspace.build, binaries, executables)
        with mutated(workspace, mutant) as state:
            built, first_failed = None, False
            if syntax_check(workspace, mutant):
                # The test tree's unit tests of its line (none: nothing to build there), then the
                # scenarios' firmware.
                trees = [(workspace, targets)] if targets != [] or scenario_tree is None else []
                trees += [(scenario_tree, scenario_binaries)] if scenario_tree else []
                for number_built, (tree, chosen) in enumerate(trees):
                    built = tree.compile(jobs, chosen)
                    if built.returncode != 0:
                        first_failed = number_built == 0
                        break
            build_s = time.monotonic() - started
            if built is None or built.returncode != 0:
                state["untouched_outputs"] = built is None or first_failed
                state["nothing_built"] = built is None
                result.update(compiled=False, seconds={"build": round(build_s, 1)})
                why = "its line does not compile" if built is None else "does not build"
                print(f"mutate: {number} {mutant.id}: {why}, dropped ({build_s:.0f} s)", flush=True)
            else:
                if scenario_tree is not None:
                    keep_scenario_firmware(scenario_tree, scenario_binaries, folder)
                names = (
                    None if executables is None else [n for e in executables for n in unit_groups.get(e, [])]
                )
                if names == []:
                    failed, timeout, unit_s = [], None, 0.0
                else:
                    failed, timeout, unit_s = ctest(
                        workspace.build, jobs, unit_timeout, folder / "ctest.xml", names
                    )
                result.update(
                    compiled=True,
                    unit={"killed_by": failed, "timeout": timeout, "selected": names},
                    seconds={"build": round(build_s, 1), "unit": round(unit_s, 1)},
                )
                verdict = f"killed by {len(failed)} unit tests" if failed else (timeout or "unit tests pass")
                which = "all" if names is None else f"{len(names)} executing its line"
                print(
                    f"mutate: {number} {mutant.id}: {verdict} ({which}; "
                    f"{build_s:.0f} s build, {unit_s:.0f} s tests)",
                    flush=True,
                )
        report.write_json(result_path, result)
    return tried


def needed_targets(
    build: Path, binaries: Sequence[str], executables: Iterable[str] | None
) -> list[str] | None:
    """What a mutant's build makes: the firmware its scenarios start and the unit-test executables
    that execute its line (ctest's, by name: build/bin/<name>); None (everything) without a
    coverage record or for an executable not where ctest runs it from."""
    if executables is None:
        return None
    tests = [f"bin/{name}" for name in executables]
    if not all((build / test).exists() for test in tests):
        return None
    return [*binaries, *tests]


def outcome_of(result: dict, equivalents: dict[str, str]) -> report.Outcome:
    unit = result.get("unit")
    scenarios = result.get("scenarios")
    approved = result.get("approved", scenarios)
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
        approved_killed_by=approved["killed_by"] if approved else None,
        equivalent=equivalents.get(result["id"]),
        seconds=result.get("seconds", {}),
    )


def write_report(
    out: Path, name: str, ids: Sequence[str], source_root: Path, config: dict
) -> list[report.Outcome]:
    equivalents = load_equivalents()
    outcomes = []
    commits: Counter[str] = Counter()
    for mutant_id in ids:
        path = out / "mutants" / mutant_id / "result.json"
        if path.exists():
            result = json.loads(path.read_text())
            outcomes.append(outcome_of(result, equivalents))
            commits[result.get("judged_at", "unknown")] += 1
    config = {**config, "judged_at": dict(commits)}
    sources = {o.path: (source_root / o.path).read_text() for o in outcomes}
    report.write_json(out / f"{name}.json", report.to_stryker(outcomes, sources, config))
    text = report.summary(outcomes, f"mutation testing: {config['description']}")
    if len(commits) > 1:  # a run that went on from kept verdicts, or over commits
        text += "\njudged at: " + ", ".join(f"{c[:12]} ({n})" for c, n in commits.most_common()) + "\n"
    report.write_atomically(out / f"{name}.txt", text)
    print(text)
    print(
        f"mutate: report {out / (name + '.json')} (mutation-testing-report-schema), "
        f"summary {out / (name + '.txt')}"
    )
    return outcomes


@dataclass(frozen=True)
class Selection:
    """The mutants a `run`, `report` or `list` call is about, and how its report names them:
    the stratified plan, or the mutants named by id."""

    plan: sampling.Plan | None
    chosen: list[Mutant]
    source_root: Path
    description: str
    report_name: str
    config: dict[str, object]

    @property
    def plan_name(self) -> str:
        """The file, in the run's folder, of the mutants a run tried: one per shard, so that shards
        run side by side in one folder (their mutants are disjoint) keep theirs apart."""
        return "plan.json" if self.report_name == "report" else f"{self.report_name}-plan.json"

    def universe(self) -> list[str]:
        """Every mutant the run may try: the plan's candidates (or those chosen by id)."""
        if self.plan is None:
            return [m.id for m in self.chosen]
        return [m.id for mutants in self.plan.candidates.values() for m in mutants]

    def candidates(self, out: Path) -> Iterable[Mutant]:
        if self.plan is None:
            return self.chosen
        equivalents = load_equivalents()
        return sampling.take(self.plan, lambda m: counted(out, m, equivalents))


def host_tree(args: argparse.Namespace) -> tuple[Path, Path]:
    """The built tree whose compiled files the sample draws from, and its sources: the run's
    own workspace once built (`report`, `list --out`), else the checkout's `make build` tree."""
    out = Path(args.out).resolve()
    if (out / "build" / ".ninja_deps").exists():
        return out / "build", out / "src"
    source_root = Path(args.source).resolve()
    return source_root / "build", source_root


def select(args: argparse.Namespace, tree: tuple[Path, Path] | None = None) -> Selection:
    """The stratified sample (or its shard) of every mutant of the product files that the host
    build compiles (`tree`: a built tree and its sources, default `host_tree`); `--mutant ID`s
    instead, where the command has them."""
    shard = scenario_shards.parse_shard(args.shard) if args.shard else None
    if args.mutants < 1:
        raise ValueError(f"MUTANTS must be at least 1, not {args.mutants}")
    source_root = Path(args.source).resolve()
    product = product_files(source_root, args.product or PRODUCT)
    compiled = compiled_by(*(tree or host_tree(args)))
    files = [f for f in product if f in compiled]
    outside = [f for f in product if f not in compiled]
    # The index of sibling names stays that of every product file: the mutants do not change.
    everything = [m for m in all_mutants(source_root, product) if m.path in compiled]
    plan = None
    if getattr(args, "mutant", None):
        by_id = {m.id: m for m in everything}
        unknown = [i for i in args.mutant if i not in by_id]
        if unknown:
            raise ValueError(
                f"no such mutant of a file the host build compiles: {', '.join(unknown)} "
                "(`tools/mutate.py list` shows a sample's ids)"
            )
        chosen = [by_id[i] for i in args.mutant]
        description = f"{len(chosen)} mutants chosen by id"
    else:
        plan = sampling.plan(
            everything, args.mutants, args.seed, (shard.index, shard.count) if shard else None
        )
        chosen = sampling.first_choices(plan)
        where = f", shard {shard}" if shard else ""
        description = (
            f"{plan.count} counted mutants stratified over {len(plan.targets)} files, "
            f"of {len(everything)} (seed {args.seed}{where})"
        )
    not_sampled = {}
    if outside:
        folders = sorted({str(Path(f).parent) for f in outside})
        description += (
            f"; not sampled: {len(outside)} product files the host build does not compile "
            f"({', '.join(folders)}: built and tested by their own targets)"
        )
        not_sampled = {"not_sampled": outside}
    config = {
        "description": description,
        "seed": args.seed,
        "mutants": args.mutants,
        "shard": str(shard) if shard else None,
        "project_root": str(source_root),
        **not_sampled,
    }
    name = f"report-shard-{shard.index}-of-{shard.count}" if shard else "report"
    return Selection(
        plan, chosen, source_root, f"{description}; {len(files)} product files sampled", name, config
    )


def run_in_vm(out: Path, command: str, uml: bool, extra: Sequence[str] = ()) -> int:
    """`tools/mutate.py COMMAND --out OUT` inside tools/with-vcan (user-mode Linux allowed or not)."""
    argv = [str(REPO / "tools" / "with-vcan"), *([] if uml else ["--no-uml"]), "--"]
    argv += [sys.executable, str(Path(__file__).resolve()), command, "--out", str(out), *extra]
    # A group of its own, stopped as a whole on Ctrl-C or SIGTERM: subprocess.run would kill
    # only with-vcan and leave the VM (qemu, virtiofsd) running.
    process = subprocess.Popen(argv, cwd=REPO, start_new_session=True)
    try:
        return process.wait()
    except BaseException:
        stop_group(process, grace_s=30)
        raise


def run_command(args: argparse.Namespace) -> int:
    out = Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    source_root = Path(args.source).resolve()
    workspace = Workspace(out, source_root, tuple(args.sources), tuple(args.cmake_arg or CMAKE_ARGS))
    scenario_tree = None if args.no_scenarios else scenario_tree_of(workspace)
    prepare(workspace, args.jobs, scenario_tree)
    chosen = select(args, (workspace.build, workspace.src))
    print(f"mutate: {chosen.description}", flush=True)
    if not args.again:
        seeded = kept_verdicts.seed(out, source_root, chosen.universe(), Path(args.kept))
        if seeded:
            print(
                f"mutate: {seeded} mutants start from their verdicts kept in {args.kept} "
                "(their files unchanged since)",
                flush=True,
            )
    tried = build_and_unit(
        workspace,
        chosen.candidates(out),
        args.jobs,
        scenario_tree,
        use_coverage=not args.no_coverage,
        again=args.again,
    )
    plan_path = out / chosen.plan_name
    report.write_json(plan_path, {"mutants": [m.id for m in tried]})
    if not args.no_scenarios:
        collect_scenarios(out)
        if not args.no_coverage:
            ensure_scenario_coverage(out)
        print(
            "mutate: bus-level scenarios of every built mutant (its release firmware), in one "
            "user-mode Linux VM (tools/with-vcan)",
            flush=True,
        )
        code = run_in_vm(out, "scenarios", uml=True, extra=["--plan", chosen.plan_name])
        if code != 0:
            print(
                f"mutate: the scenario stage ended with exit {code}; the report shows what ran",
                file=sys.stderr,
            )
    write_report(out, chosen.report_name, [m.id for m in tried], chosen.source_root, chosen.config)
    return 0


def one_line(code: str) -> str:
    return " ".join(code.split("\n")).strip()


def report_command(args: argparse.Namespace) -> int:
    """The report of a run from the results kept so far, nothing built or run."""
    chosen = select(args)
    out = Path(args.out).resolve()
    plan_path = out / chosen.plan_name
    ids = (
        json.loads(plan_path.read_text())["mutants"] if plan_path.exists() else [m.id for m in chosen.chosen]
    )
    write_report(out, chosen.report_name, ids, chosen.source_root, chosen.config)
    return 0


def list_command(args: argparse.Namespace) -> int:
    for mutant in select(args).chosen:
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
        p.add_argument(
            "--mutants",
            type=int,
            default=40,
            help="how many counted mutants (compiled, not equivalent; default 40)",
        )
        p.add_argument("--seed", type=int, default=1, help="the sample's seed (default 1)")
        p.add_argument("--shard", help="K/N: the K-th of N shards of the sample")
        p.add_argument("--source", default=str(REPO), help=argparse.SUPPRESS)
        p.add_argument("--product", action="append", help=argparse.SUPPRESS)
    sub.choices["report"].add_argument(
        "--out", default=str(DEFAULT_OUT), help="the run's folder (default build/mutate)"
    )
    sub.choices["list"].add_argument(
        "--out",
        default=str(DEFAULT_OUT),
        help="a run's folder: its build (else the checkout's build/) tells which files are sampled",
    )
    run = sub.choices["run"]
    run.add_argument("--out", default=str(DEFAULT_OUT), help="workspace and report (default build/mutate)")
    run.add_argument("--jobs", type=int, default=os.cpu_count() or 2, help="build and ctest parallelism")
    run.add_argument("--no-scenarios", action="store_true", help="unit tests only (no VM)")
    run.add_argument(
        "--no-coverage", action="store_true", help="every test on every mutant (no coverage record)"
    )
    run.add_argument(
        "--mutant", action="append", metavar="ID", help="run this mutant (repeatable), not a sample"
    )
    run.add_argument(
        "--again",
        action="store_true",
        help="judge the mutants again though a result on the same source is kept (after adding a "
        "test that should kill a survivor: --mutant ID --again)",
    )
    run.add_argument("--sources", nargs="+", default=list(SOURCES), help=argparse.SUPPRESS)
    run.add_argument("--cmake-arg", action="append", help=argparse.SUPPRESS)
    run.add_argument("--kept", default=str(kept_verdicts.KEPT), help=argparse.SUPPRESS)
    keep = sub.add_parser(
        "keep",
        help="add a run's finished verdicts to tools/mutants-judged.json (commit it: a later run "
        "on another machine starts from them)",
    )
    keep.add_argument("--out", default=str(DEFAULT_OUT), help="the run's folder (default build/mutate)")
    keep.add_argument("--kept", default=str(kept_verdicts.KEPT), help=argparse.SUPPRESS)
    keep.add_argument(
        "--judged-at",
        metavar="COMMIT",
        help="the commit that verdicts naming none were judged at (a run begun before `keep` "
        "existed; default: the checkout's)",
    )
    merge = sub.add_parser("merge", help="merge shards' reports")
    merge.add_argument("reports", nargs="+")
    merge.add_argument("--out", required=True)
    scen = sub.add_parser("scenarios", help="(inside tools/with-vcan) the scenario layer of a run")
    scen.add_argument("--out", default=str(DEFAULT_OUT))
    scen.add_argument("--plan", default="plan.json", help="the run's plan file in OUT")
    cov = sub.add_parser("coverage", help="(inside tools/with-vcan) the scenarios' coverage record")
    cov.add_argument("--out", default=str(DEFAULT_OUT))
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
        if args.command == "keep":
            added, total = kept_verdicts.keep(Path(args.out).resolve(), Path(args.kept), args.judged_at)
            print(f"mutate: {added} verdicts added to {args.kept} ({total} kept)")
            return 0
        if args.command == "merge":
            return merge_command(args)
        if args.command == "coverage":
            return coverage_command(Path(args.out))
        return scenarios_command(Path(args.out), args.plan)
    except (ValueError, OSError, KeyError) as error:  # a bad SHARD, a missing or foreign report
        print(f"mutate: {type(error).__name__}: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("mutate: stopped; the results so far are kept (run again to go on)", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
