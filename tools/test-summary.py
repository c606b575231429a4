"""Summarise a test run from the JUnit XML files of its stages.

Prints how many C++ tests, Python unit tests and bus-level scenarios ran, which bus path the
scenarios used, how many lockstep scenarios ran on the timed bus and how many on the ideal bus
and why (each scenario's BUS_PROPERTY), one line per failure with the pictures it left (the
[[ATTACHMENT|path]] lines hilrig's pytest plugin writes into the failure's system-out), the
coverage of the project's requirements (each test's `requirement` JUnit properties against the
`hil_requirements` file pytest.ini names: hilrig.requirements), and closes with the plain
"N passed, N failed" line.
Exits non-zero when a stage is missing, collected nothing, or had failures.

    python tools/test-summary.py out/test-results [--shard K/N] [--bus-only] [--requirements FILE]

--shard K/N: the run was one CI job of N (`make test SHARD=K/N`): the unit stages are expected
in shard 1 only. --bus-only: the bus-level stage alone (`make durations`). --requirements FILE:
the requirements file (default: the one the checkout's pytest.ini names).
"""

from __future__ import annotations

import argparse
import re
import sys
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

from scenario_shards import Shard, parse_shard  # tools/, this script's own folder

from hilrig import requirements
from hilrig.errors import ConfigurationError
from hilrig.wire.bustime import BUS_PROPERTY, bus_summary

CHECKOUT_INI = Path(__file__).resolve().parent.parent / "pytest.ini"

# The stages that run in every shard; the others run in shard 1 (tools/run-tests).
BUS_STAGE = "bus-level scenarios"
BROWSER_STAGE = "dashboards in browser"
"""Stage 4: the bus stage's firmware traces in headless Chromium; in a shard, only the traces
that shard made (so it may check none), and not run with the bus stage alone."""
STAGES = (
    ("cpp.xml", "C++ unit tests"),
    ("cortex-m.xml", "Cortex-M unit tests"),
    ("python-unit.xml", "Python unit tests"),
    ("scenarios*.xml", BUS_STAGE),
    ("browser*.xml", BROWSER_STAGE),
)
EVERY_SHARD = (BUS_STAGE, BROWSER_STAGE)


@dataclass
class StageResult:
    passed: int = 0
    failed: int = 0
    skipped: int = 0
    failures: list[str] = field(default_factory=list)
    attachments: dict[str, list[str]] = field(default_factory=dict)
    """Per failure, the files it attached (pictures of the failed checks)."""
    cases: list[requirements.CaseResult] = field(default_factory=list)
    """Each test that names a requirement, with its outcome."""
    platforms: dict[str, list[int]] = field(default_factory=dict)
    """Per firmware platform (the scenarios' PLATFORM_PROPERTY), [passed, failed] of the scenarios
    whose firmware ran on it."""
    buses: list[list[str]] = field(default_factory=list)
    """Each scenario's buses (BUS_PROPERTY: a bit rate, or the ideal bus and why), of those that
    ran and named theirs."""


PLATFORM_PROPERTY = "firmware_platform"
"""hilrig.pytest_plugin.fixtures.PLATFORM_PROPERTY (this script imports no pytest plugin)."""


ATTACHMENT = re.compile(r"\[\[ATTACHMENT\|(?P<path>[^\]]+)\]\]")


def read_junit(path: Path) -> StageResult:
    result = StageResult()
    for case in ET.parse(path).getroot().iter("testcase"):
        name = f"{case.get('classname', '')}::{case.get('name', '')}".strip(":")
        if case.find("failure") is not None or case.find("error") is not None:
            result.failed += 1
            result.failures.append(name)
            out = "".join(element.text or "" for element in case.iter("system-out"))
            if found := [match["path"] for match in ATTACHMENT.finditer(out)]:
                result.attachments[name] = found
            outcome = requirements.FAILED
        elif case.find("skipped") is not None:
            result.skipped += 1
            outcome = requirements.SKIPPED
        else:
            result.passed += 1
            outcome = requirements.PASSED
        if outcome != requirements.SKIPPED:
            if buses := [p.get("value", "") for p in case.iter("property") if p.get("name") == BUS_PROPERTY]:
                result.buses.append(buses)
            for platform in {
                p.get("value", "") for p in case.iter("property") if p.get("name") == PLATFORM_PROPERTY
            }:
                counts = result.platforms.setdefault(platform, [0, 0])
                counts[0 if outcome == requirements.PASSED else 1] += 1
        named = tuple(
            p.get("value", "") for p in case.iter("property") if p.get("name") == requirements.PROPERTY
        )
        if named:
            result.cases.append(requirements.CaseResult(name, named, outcome))
    return result


def requirement_lines(
    path: Path | None, cases: list[requirements.CaseResult], shard: Shard | None
) -> list[str]:
    """Each requirement's verdict over every stage's tests (hilrig.requirements); nothing where
    the project has no requirements file."""
    if path is None:
        return []
    try:
        known = requirements.load(path)
    except ConfigurationError as error:
        return [f"requirements: {error}"]
    label = f"requirements of {path.name}" + (", this shard's tests only" if shard is not None else "")
    return requirements.coverage(known, cases).lines(label)


def shard_spec(text: str) -> Shard:
    try:
        return parse_shard(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description="Summarise a test run from its JUnit XML files.")
    parser.add_argument("results", type=Path, help="the folder of the JUnit XML files")
    parser.add_argument("--shard", type=shard_spec, help="K/N: the run was shard K of N")
    parser.add_argument("--bus-only", action="store_true", help="the run had the bus-level stage alone")
    parser.add_argument(
        "--requirements", type=Path, help="the requirements file (default: hil_requirements of pytest.ini)"
    )
    options = parser.parse_args(argv[1:])
    results: Path = options.results
    shard: Shard | None = options.shard
    ok = True
    total_passed = total_failed = total_skipped = bus_ran = 0
    cases: list[requirements.CaseResult] = []
    for file_name, title in STAGES:
        if title != BUS_STAGE and options.bus_only:
            print(f"{title:22} not run (bus-level stage only)")
            continue
        if title not in EVERY_SHARD and shard is not None and shard.index != 1:
            print(f"{title:22} not in this shard (shard 1/{shard.count} runs it)")
            continue
        paths = sorted(results.glob(file_name))
        if not paths:
            print(f"{title:22} did not run (no {results / file_name})")
            ok = False
            continue
        stage = StageResult()
        for path in paths:  # a stage may write several files (parallel and serial passes)
            part = read_junit(path)
            stage.passed += part.passed
            stage.failed += part.failed
            stage.skipped += part.skipped
            stage.failures += part.failures
            stage.attachments |= part.attachments
            stage.buses += part.buses
            cases += part.cases
            for platform, (passed, failed) in part.platforms.items():
                counts = stage.platforms.setdefault(platform, [0, 0])
                counts[0] += passed
                counts[1] += failed
        ran = stage.passed + stage.failed
        line = f"{title:22} {ran:4d} ran: {stage.passed} passed, {stage.failed} failed"
        if stage.skipped:
            line += f", {stage.skipped} skipped"
        print(line)
        if stage.platforms:
            print(
                "    firmware platforms: "
                + ", ".join(
                    f"{p} {n + f} ran ({n} passed, {f} failed)"
                    for p, (n, f) in sorted(stage.platforms.items())
                )
            )
        for bus_line in bus_summary(stage.buses):
            print(f"    {bus_line}")
        for name in stage.failures:
            print(f"    FAILED {name}")
            for attached in stage.attachments.get(name, []):
                print(f"        picture: {attached}")
        if stage.failed or (ran == 0 and not (title == BROWSER_STAGE and shard is not None)):
            ok = False
        if title == BUS_STAGE:
            bus_ran = ran + stage.skipped
        total_passed += stage.passed
        total_failed += stage.failed
        total_skipped += stage.skipped
    if shard is not None:
        print(
            f"shard {shard}: {bus_ran} bus-level scenarios"
            f" (the C++ and Python unit stages run in shard 1/{shard.count})"
        )
    bus_path = results / "bus-path.txt"
    where = bus_path.read_text().strip() if bus_path.exists() else "unknown (the bus stage did not start)"
    print(f"bus path used by the scenarios: {where}")
    required = options.requirements or requirements.ini_requirements(CHECKOUT_INI)
    for line in requirement_lines(required, cases, shard):
        print(line)
    closing = f"{total_passed} passed, {total_failed} failed"
    if total_skipped:
        closing += f", {total_skipped} skipped"
    print(closing)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv))
