"""Summarise a test run from the JUnit XML files of its stages.

Prints how many C++ tests, Python unit tests and bus-level scenarios ran, which bus path the
scenarios used, one line per failure, and closes with the plain "N passed, N failed" line.
Exits non-zero when a stage is missing, collected nothing, or had failures.

    python tools/test-summary.py out/test-results
"""

from __future__ import annotations

import sys
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

STAGES = (
    ("cpp.xml", "C++ unit tests"),
    ("python-unit.xml", "Python unit tests"),
    ("scenarios*.xml", "bus-level scenarios"),
)


@dataclass
class StageResult:
    passed: int = 0
    failed: int = 0
    skipped: int = 0
    failures: list[str] = field(default_factory=list)


def read_junit(path: Path) -> StageResult:
    result = StageResult()
    for case in ET.parse(path).getroot().iter("testcase"):
        name = f"{case.get('classname', '')}::{case.get('name', '')}".strip(":")
        if case.find("failure") is not None or case.find("error") is not None:
            result.failed += 1
            result.failures.append(name)
        elif case.find("skipped") is not None:
            result.skipped += 1
        else:
            result.passed += 1
    return result


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print("usage: test-summary.py RESULTS_DIR", file=sys.stderr)
        return 2
    results = Path(argv[1])
    ok = True
    total_passed = total_failed = total_skipped = 0
    for file_name, title in STAGES:
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
        ran = stage.passed + stage.failed
        line = f"{title:22} {ran:4d} ran: {stage.passed} passed, {stage.failed} failed"
        if stage.skipped:
            line += f", {stage.skipped} skipped"
        print(line)
        for name in stage.failures:
            print(f"    FAILED {name}")
        if ran == 0 or stage.failed:
            ok = False
        total_passed += stage.passed
        total_failed += stage.failed
        total_skipped += stage.skipped
    bus_path = results / "bus-path.txt"
    where = bus_path.read_text().strip() if bus_path.exists() else "unknown (the bus stage did not start)"
    print(f"bus path used by the scenarios: {where}")
    closing = f"{total_passed} passed, {total_failed} failed"
    if total_skipped:
        closing += f", {total_skipped} skipped"
    print(closing)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv))
