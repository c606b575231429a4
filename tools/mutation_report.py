"""The verdict of a mutation run: each mutant's outcome, the scores, and the report files.

A mutant's outcome comes from the two test layers `tools/mutate.py` runs on it: the C++ unit
tests (ctest) and the bus-level lockstep scenarios (pytest in the micro-VM). The scores are
counted over the mutants that compiled and were not reviewed as equivalent:

- scenarios: killed by the scenarios' own assertions (approved traces off);
- scenarios with approved traces: killed by the assertions or the approved-trace checks;
- overall: unit tests plus scenarios with approved traces;
- unit tests alone;
each with its 95 % confidence interval (Wilson's score interval), and per component (the
folder of the mutated file under firmware/). A timeout of a layer is a kill only as the layer
decided it (against the unmutated firmware's own time); one with no verdict leaves it pending.

The report is written in Stryker's mutation-testing-report-schema (version 2), so its viewers
(the mutation-testing-elements HTML report, Stryker Dashboard) show it; the layer that killed a
mutant is the prefix of each `killedBy` test id ("unit:" or "scenario:"), which is all `merge`
needs to count the scores again from reports alone.
"""

from __future__ import annotations

import difflib
import json
import math
import os
import tempfile
from collections import defaultdict
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

SCHEMA_VERSION = "2"
UNIT_PREFIX = "unit:"
SCENARIO_PREFIX = "scenario:"
THRESHOLDS = {"high": 97, "low": 90}
"""The goals: the scenarios' own assertions 90 % (the interval's lower bound 85 %), unit tests
plus scenarios with approved traces 97 %."""
Z_95 = 1.959964
"""The standard normal quantile of a two-sided 95 % interval."""


@dataclass
class Outcome:
    """What happened to one mutant: built or not, and which tests of each layer failed on it
    (None: that layer did not run). A timed-out layer is a kill whose reason says so."""

    id: str
    path: str
    line: int
    original: str
    replacement: str
    rule: str
    compiled: bool = True
    unit_killed_by: list[str] | None = None
    unit_timeout: str | None = None
    scenario_killed_by: list[str] | None = None
    scenario_timeout: str | None = None
    approved_killed_by: list[str] | None = None
    """The scenarios' verdict with the approved traces checked (the assertions' if none)."""
    equivalent: str | None = None
    """The reviewed reason when the mutant is listed as equivalent (not counted)."""
    seconds: dict[str, float] = field(default_factory=dict)
    """Wall time per phase: build, unit, scenarios."""

    @property
    def by_unit(self) -> bool:
        return bool(self.unit_killed_by) or self.unit_timeout is not None

    @property
    def by_scenarios(self) -> bool:
        return bool(self.scenario_killed_by) or self.scenario_timeout is not None

    @property
    def by_approved(self) -> bool:
        return bool(self.approved_killed_by) or self.by_scenarios

    @property
    def killed(self) -> bool:
        return self.by_unit or self.by_approved

    @property
    def counted(self) -> bool:
        return self.compiled and self.equivalent is None

    @property
    def status(self) -> str:
        """The Stryker status."""
        if not self.compiled:
            return "CompileError"
        if self.equivalent is not None:
            return "Ignored"
        if self.unit_killed_by or self.scenario_killed_by or self.approved_killed_by:
            return "Killed"
        if self.by_unit or self.by_scenarios:
            return "Timeout"
        if self.unit_killed_by is None and self.scenario_killed_by is None:
            return "Pending"
        return "Survived"

    @property
    def component(self) -> str:
        parts = Path(self.path).parts
        return "/".join(parts[1:-1]) or parts[0]

    def diff(self) -> str:
        return "".join(
            difflib.unified_diff(
                [self.original], [self.replacement], f"a/{self.path}", f"b/{self.path}", n=0, lineterm="\n"
            )
        ).replace("@@ -1 +1 @@", f"@@ -{self.line} +{self.line} @@")


@dataclass(frozen=True)
class Score:
    killed: int
    total: int

    @property
    def percent(self) -> float | None:
        return 100.0 * self.killed / self.total if self.total else None

    @property
    def interval(self) -> tuple[float, float] | None:
        """The 95 % confidence interval of the kill rate, in percent (Wilson)."""
        return wilson(self.killed, self.total)

    def __str__(self) -> str:
        percent, interval = self.percent, self.interval
        if percent is None or interval is None:
            return f"{self.killed}/{self.total}"
        return f"{self.killed}/{self.total} = {percent:.1f} % (95 % CI {interval[0]:.1f}-{interval[1]:.1f} %)"


def wilson(killed: int, total: int, z: float = Z_95) -> tuple[float, float] | None:
    """Wilson's score interval of a proportion, in percent: right at 0 and at all, unlike the
    normal approximation; 14 of 15 gives 70.2-98.8 %."""
    if total <= 0:
        return None
    p = killed / total
    denominator = 1 + z * z / total
    centre = (p + z * z / (2 * total)) / denominator
    half = z * math.sqrt(p * (1 - p) / total + z * z / (4 * total * total)) / denominator
    return 100.0 * max(0.0, centre - half), 100.0 * min(1.0, centre + half)


@dataclass(frozen=True)
class Scores:
    overall: Score
    unit: Score
    scenarios: Score
    by_component: dict[str, Score]
    compile_errors: int
    equivalent: int
    pending: int
    approved: Score = Score(0, 0)
    scenarios_by_component: dict[str, Score] = field(default_factory=dict)


def scores(outcomes: Iterable[Outcome]) -> Scores:
    outcomes = list(outcomes)
    done = [o for o in outcomes if o.counted and o.status != "Pending"]
    components: dict[str, list[Outcome]] = defaultdict(list)
    for outcome in done:
        components[outcome.component].append(outcome)
    with_scenarios = [o for o in done if o.scenario_killed_by is not None]
    return Scores(
        overall=Score(sum(o.killed for o in done), len(done)),
        unit=Score(sum(o.by_unit for o in done), sum(o.unit_killed_by is not None for o in done)),
        scenarios=Score(sum(o.by_scenarios for o in with_scenarios), len(with_scenarios)),
        approved=Score(sum(o.by_approved for o in with_scenarios), len(with_scenarios)),
        by_component={
            name: Score(sum(o.killed for o in group), len(group))
            for name, group in sorted(components.items())
        },
        scenarios_by_component={
            name: Score(
                sum(o.by_scenarios for o in group if o.scenario_killed_by is not None),
                sum(o.scenario_killed_by is not None for o in group),
            )
            for name, group in sorted(components.items())
        },
        compile_errors=sum(not o.compiled for o in outcomes),
        equivalent=sum(o.compiled and o.equivalent is not None for o in outcomes),
        pending=sum(o.counted and o.status == "Pending" for o in outcomes),
    )


# --- Stryker's schema ------------------------------------------------------------------------
def to_stryker(
    outcomes: Iterable[Outcome], sources: Mapping[str, str], config: dict[str, Any]
) -> dict[str, Any]:
    """The report as mutation-testing-report-schema v2 (`sources`: each mutated file's text)."""
    files: dict[str, dict[str, Any]] = {}
    for o in sorted(outcomes, key=lambda o: (o.path, o.line, o.id)):
        entry = files.setdefault(
            o.path, {"language": "cpp", "source": sources.get(o.path, ""), "mutants": []}
        )
        original = o.original.rstrip("\n")
        width = max(len(original), 1)
        mutant: dict[str, Any] = {
            "id": o.id,
            "mutatorName": o.rule,
            "replacement": o.replacement.rstrip("\n").strip(),
            "location": {
                "start": {"line": o.line, "column": 1},
                "end": {"line": o.line, "column": width + 1},
            },
            "status": o.status,
            "killedBy": [UNIT_PREFIX + t for t in o.unit_killed_by or []]
            + [SCENARIO_PREFIX + t for t in o.scenario_killed_by or []],
            "static": False,
            "description": original.strip() + "  ->  " + o.replacement.rstrip("\n").strip(),
        }
        reasons = [r for r in (o.unit_timeout, o.scenario_timeout, o.equivalent) if r]
        if reasons:
            mutant["statusReason"] = "; ".join(reasons)
        if not o.compiled:
            mutant["statusReason"] = "does not compile"
        mutant["hilrig"] = {
            "original": o.original,
            "mutated": o.replacement,
            "layers": {
                "unit": _layer(o.unit_killed_by, o.unit_timeout),
                "scenarios": _layer(o.scenario_killed_by, o.scenario_timeout),
                "approved": _layer(o.approved_killed_by, None),
            },
            "seconds": o.seconds,
        }
        entry["mutants"].append(mutant)
    return {
        "$schema": "https://git.io/mutation-testing-schema",
        "schemaVersion": SCHEMA_VERSION,
        "thresholds": THRESHOLDS,
        "projectRoot": config.get("project_root", ""),
        "files": files,
        "framework": {"name": "hilrig mutate (universalmutator rules)"},
        "config": config,
    }


def _layer(killed_by: list[str] | None, timeout: str | None) -> dict[str, Any] | None:
    if killed_by is None:
        return None
    return {"killed_by": killed_by, "timeout": timeout}


def from_stryker(report: Mapping[str, Any]) -> list[Outcome]:
    """The outcomes a report written by `to_stryker` holds (for `merge`)."""
    outcomes = []
    for path, entry in report["files"].items():
        for mutant in entry["mutants"]:
            extra = mutant.get("hilrig", {})
            layers = extra.get("layers", {})
            unit, scenarios = layers.get("unit"), layers.get("scenarios")
            approved = layers.get("approved", scenarios)
            outcomes.append(
                Outcome(
                    id=mutant["id"],
                    path=path,
                    line=mutant["location"]["start"]["line"],
                    original=extra.get("original", ""),
                    replacement=extra.get("mutated", mutant.get("replacement", "")),
                    rule=mutant["mutatorName"],
                    compiled=mutant["status"] != "CompileError",
                    unit_killed_by=None if unit is None else unit["killed_by"],
                    unit_timeout=None if unit is None else unit["timeout"],
                    scenario_killed_by=None if scenarios is None else scenarios["killed_by"],
                    scenario_timeout=None if scenarios is None else scenarios["timeout"],
                    approved_killed_by=None if approved is None else approved["killed_by"],
                    equivalent=mutant.get("statusReason") if mutant["status"] == "Ignored" else None,
                    seconds=extra.get("seconds", {}),
                )
            )
    return outcomes


def merge(reports: Iterable[Mapping[str, Any]]) -> dict[str, Any]:
    """Shards' reports as one: their mutants (a mutant in two reports must agree), the sources,
    and the config of the first with the shards listed."""
    outcomes: dict[str, Outcome] = {}
    sources: dict[str, str] = {}
    configs = []
    for report in reports:
        configs.append(report.get("config", {}))
        for path, entry in report["files"].items():
            sources.setdefault(path, entry.get("source", ""))
        for outcome in from_stryker(report):
            known = outcomes.get(outcome.id)
            if known is not None and known.status != outcome.status:
                raise ValueError(
                    f"mutant {outcome.id} is {known.status} in one report and {outcome.status} in another"
                )
            outcomes[outcome.id] = outcome
    config = dict(configs[0]) if configs else {}
    config["merged_shards"] = [c.get("shard") for c in configs]
    return to_stryker(outcomes.values(), sources, config)


# --- The summary people read -----------------------------------------------------------------
def summary(outcomes: Iterable[Outcome], title: str) -> str:
    outcomes = list(outcomes)
    s = scores(outcomes)
    lines = [title, ""]
    lines.append(f"mutants                      {len(outcomes)}")
    lines.append(f"  do not compile (dropped)   {s.compile_errors}")
    lines.append(f"  reviewed as equivalent     {s.equivalent}")
    if s.pending:
        lines.append(f"  not run to the end         {s.pending}")
    lines.append(f"  counted                    {s.overall.total}")
    lines.append("")
    lines.append(f"killed by unit tests + scenarios   {s.overall}")
    lines.append(f"killed by unit tests alone         {s.unit}")
    lines.append(f"killed by scenarios alone          {s.scenarios}")
    lines.append(f"  with approved traces             {s.approved}")
    lines.append("")
    lines.append("per component: scenarios' own assertions | unit tests + scenarios with approved traces")
    for name, score in s.by_component.items():
        lines.append(f"  {name:<28} {s.scenarios_by_component.get(name, Score(0, 0))!s:<40} | {score}")
    timed = [o for o in outcomes if o.compiled and o.seconds]
    if timed:
        lines.append("")
        lines.append("seconds per mutant (median, max)")
        for phase in ("build", "unit", "scenarios"):
            values = sorted(o.seconds[phase] for o in timed if phase in o.seconds)
            if values:
                lines.append(f"  {phase:<10} {values[len(values) // 2]:8.1f} {values[-1]:8.1f}")
    per_counted = cost_per_counted(outcomes)
    if per_counted is not None:
        lines.append(
            f"  all phases: {per_counted:.0f} s of wall time per counted mutant (the dropped ones' "
            f"builds included): 200 counted in {200 * per_counted / 3600:.1f} h, on this host at its load"
        )
    survivors = [o for o in outcomes if o.status == "Survived"]
    scenario_survivors = [
        o for o in outcomes if o.scenario_killed_by is not None and o.counted and not o.by_approved
    ]
    lines.append("")
    lines.append(f"survivors ({len(survivors)}): no test failed")
    for o in survivors:
        lines.append(f"  {o.id} ({o.rule})")
        lines.extend("    " + line for line in o.diff().splitlines())
    assertions_only = [o for o in outcomes if o.counted and o.by_approved and not o.by_scenarios]
    lines.append("")
    lines.append(f"killed by the approved traces only ({len(assertions_only)}): the assertions let them pass")
    for o in assertions_only:
        lines.append(f"  {o.id} ({o.rule}): {', '.join(o.approved_killed_by or [])[:160]}")
        lines.extend("    " + line for line in o.diff().splitlines())
    others = [o for o in scenario_survivors if o.status != "Survived"]
    lines.append("")
    lines.append(f"killed by unit tests only ({len(others)}): the scenarios let them pass")
    for o in others:
        lines.append(f"  {o.id}: {', '.join(o.unit_killed_by or [])[:160]}")
        lines.extend("    " + line for line in o.diff().splitlines())
    return "\n".join(lines) + "\n"


def cost_per_counted(outcomes: Iterable[Outcome]) -> float | None:
    """Wall seconds of every phase of every mutant tried, per counted mutant done."""
    outcomes = list(outcomes)
    done = [o for o in outcomes if o.counted and o.status != "Pending"]
    if not done:
        return None
    return sum(sum(o.seconds.values()) for o in outcomes) / len(done)


def write_atomically(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile("w", dir=path.parent, prefix=f".{path.name}.", delete=False) as tmp:
        tmp.write(text)
    os.replace(tmp.name, path)


def write_json(path: Path, data: Any) -> None:
    write_atomically(path, json.dumps(data, indent=1, sort_keys=False) + "\n")
