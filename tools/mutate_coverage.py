"""Which tests execute which lines of the firmware, recorded once per firmware source state, so
that `make mutate` runs on a mutant only the tests that execute its line.

gcov: the unmutated sources built a second time in a tree of their own (build/mutate/coverage:
Debug, no sanitizers, `--coverage`), then

- each C++ unit-test executable run alone (its ctest tests), and
- each lockstep scenario against that firmware (inside tools/with-vcan; this module is also the
  pytest plugin that gives each scenario its own GCOV_PREFIX, so the firmware processes it
  starts write their counters apart from the other scenarios');

`gcov --json-format` reads each one's counters. coverage.json keeps, per source file and
instrumented line, the tests that executed it, and the source digest it belongs to.

Selecting: a line gcov instrumented is run against the tests that executed it only (none: no
test can kill the mutant, it survives without a run); a line gcov did not instrument (a
declaration, a constant, a macro's use) against every test. A test that left no counters (its
firmware killed, not stopped) counts as executing every line.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import subprocess
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import pytest

COVERAGE_CMAKE_ARGS = (
    "-DCMAKE_BUILD_TYPE=Debug",
    "-DHIL_SANITIZE=OFF",
    "-DHIL_TESTS=ON",
    "-DCMAKE_CXX_FLAGS=--coverage",
    "-DCMAKE_EXE_LINKER_FLAGS=--coverage",
)
PREFIX_VARIABLE = "HIL_MUTATE_COVERAGE_DIR"
"""Set for the coverage scenarios: each scenario's counters go to a folder under it."""
UNIT = "unit:"
RECORD_FORMAT = 2
"""Of coverage.json: a record of another format (format 1 lost the header lines that only unity
test files ran) reads as one of other sources, so it is recorded again."""
SCENARIO = "scenario:"


def folder_name(test: str) -> str:
    """A test's counters folder: its name made safe, with a digest against collisions."""
    safe = re.sub(r"[^\w.-]+", "_", test)[-80:]
    return f"{safe}-{hashlib.sha1(test.encode()).hexdigest()[:8]}"


# --- The pytest plugin (`-p mutate_coverage`) -------------------------------------------------
@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item: pytest.Item) -> None:
    root = os.environ.get(PREFIX_VARIABLE)
    if root:
        os.environ["GCOV_PREFIX"] = str(Path(root) / folder_name(SCENARIO + item.nodeid))


# --- Reading gcov's counters ------------------------------------------------------------------
def executed_lines(counters: Path, objects_root: Path, source_root: Path) -> dict[str, dict[int, bool]]:
    """Per source file (relative to `source_root`), each instrumented line and whether it ran,
    from the .gcda files a test wrote under `counters` (GCOV_PREFIX: the object tree's absolute
    path below it). The .gcno files of `objects_root` are linked beside them for gcov."""
    gcdas = sorted(counters.rglob("*.gcda"))
    result: dict[str, dict[int, bool]] = {}
    if not gcdas:
        return result
    for gcda in gcdas:
        original = Path("/") / gcda.relative_to(counters)
        gcno = original.with_suffix(".gcno")
        link = gcda.with_suffix(".gcno")
        if gcno.exists() and not link.exists():
            link.symlink_to(gcno)
    for start in range(0, len(gcdas), 200):
        batch = [str(g) for g in gcdas[start : start + 200]]
        output = subprocess.run(
            ["gcov", "--json-format", "--stdout", *batch],
            cwd=objects_root,
            capture_output=True,
            text=True,
            check=False,
        ).stdout
        for document in output.splitlines():
            if not document.startswith("{"):
                continue
            for entry in json.loads(document).get("files", []):
                path = _relative(entry["file"], objects_root, source_root)
                if path is None:
                    continue
                lines = result.setdefault(path, {})
                for line in entry["lines"]:
                    number = line["line_number"]
                    lines[number] = lines.get(number, False) or line["count"] > 0
    return result


def _relative(file: str, objects_root: Path, source_root: Path) -> str | None:
    """A gcov file name as a path under `source_root`. A relative name is the build tree's (what
    ccache's base_dir makes of an include path) or the source tree's: the build maps the source
    tree to "." (-ffile-prefix-map), which is how a unity test file's absolute includes arrive."""
    root = source_root.resolve()
    for base in (objects_root, source_root):
        path = (base / file).resolve()
        if path.is_relative_to(root) and path.exists():
            return str(path.relative_to(root))
    return None  # a system or generated header


# --- The record ---------------------------------------------------------------------------------
@dataclass
class Coverage:
    """Tests by name, and per file and instrumented line the indices of the tests that ran it."""

    digest: str
    tests: list[str]
    lines: dict[str, dict[int, list[int]]]
    blind: list[int]
    """Tests that left no counters: they may execute anything."""

    @classmethod
    def build(cls, digest: str, per_test: dict[str, dict[str, dict[int, bool]]]) -> Coverage:
        tests = sorted(per_test)
        lines: dict[str, dict[int, list[int]]] = {}
        for number, test in enumerate(tests):
            for path, executed in per_test[test].items():
                for line, ran in executed.items():
                    users = lines.setdefault(path, {}).setdefault(line, [])
                    if ran:
                        users.append(number)
        blind = [n for n, t in enumerate(tests) if not per_test[t]]
        return cls(digest, tests, lines, blind)

    def to_json(self) -> dict:
        return {
            "format": RECORD_FORMAT,
            "digest": self.digest,
            "tests": self.tests,
            "blind": self.blind,
            "lines": {p: {str(n): users for n, users in ls.items()} for p, ls in self.lines.items()},
        }

    @classmethod
    def from_json(cls, data: dict) -> Coverage:
        lines = {p: {int(n): users for n, users in ls.items()} for p, ls in data["lines"].items()}
        digest = data["digest"] if data.get("format") == RECORD_FORMAT else "another format"
        return cls(digest, data["tests"], lines, data.get("blind", []))

    def covering(self, path: str, line: int, layer: str) -> list[str] | None:
        """The tests of `layer` (UNIT or SCENARIO prefix) that execute the line; None when the
        record cannot tell (a line not instrumented, or no test of the layer recorded)."""
        known = [n for n, t in enumerate(self.tests) if t.startswith(layer)]
        if not known:
            return None
        users = self.lines.get(path, {}).get(line)
        if users is None:
            return None
        chosen = sorted(set(users) | set(self.blind))
        return [self.tests[n][len(layer) :] for n in chosen if self.tests[n].startswith(layer)]


def merge(records: Iterable[Coverage]) -> Coverage:
    """Records of the same sources (the unit tests' and the scenarios') as one."""
    records = list(records)
    per_test: dict[str, dict[str, dict[int, bool]]] = {}
    for record in records:
        for number, test in enumerate(record.tests):
            executed: dict[str, dict[int, bool]] = {}
            if number not in record.blind:
                for path, lines in record.lines.items():
                    executed[path] = {line: number in users for line, users in lines.items()}
            per_test[test] = executed
    return Coverage.build(records[0].digest if records else "", per_test)


def sources_digest(root: Path, names: Sequence[str]) -> str:
    digest = hashlib.sha1()
    for name in names:
        origin = root / name
        files = [origin] if origin.is_file() else sorted(p for p in origin.rglob("*") if p.is_file())
        for file in files:
            if "__pycache__" not in file.parts:
                digest.update(str(file.relative_to(root)).encode() + b"\0" + file.read_bytes())
    return digest.hexdigest()


# --- The unit tests' record -------------------------------------------------------------------
def unit_tests_by_executable(build: Path) -> dict[str, list[str]]:
    """ctest's tests grouped by the executable each runs."""
    listing = subprocess.run(
        ["ctest", "--test-dir", str(build), "--show-only=json-v1"], capture_output=True, text=True, check=True
    ).stdout
    groups: dict[str, list[str]] = {}
    for test in json.loads(listing).get("tests", []):
        command = test.get("command") or ["?"]
        groups.setdefault(Path(command[0]).name, []).append(test["name"])
    return groups


def ctest_regex(names: Sequence[str]) -> str:
    return "^(" + "|".join(re.escape(n) for n in names) + ")$"


def record_unit_tests(build: Path, source_root: Path, counters: Path, digest: str, jobs: int) -> Coverage:
    """Each unit-test executable's tests alone, their counters apart: the unit layer's record.
    A unit test is named by its executable here (its tests run together for a mutant)."""
    per_test: dict[str, dict[str, dict[int, bool]]] = {}
    for executable, names in sorted(unit_tests_by_executable(build).items()):
        folder = counters / folder_name(UNIT + executable)
        env = dict(os.environ, GCOV_PREFIX=str(folder))
        subprocess.run(
            ["ctest", "--test-dir", str(build), "-j", str(jobs), "-R", ctest_regex(names)],
            env=env,
            capture_output=True,
            check=False,
        )
        per_test[UNIT + executable] = executed_lines(folder, build, source_root)
    return Coverage.build(digest, per_test)


def record_scenarios(
    ids: Sequence[str], counters: Path, build: Path, source_root: Path, digest: str
) -> Coverage:
    """The scenarios' record from the counters their run left (`scenario_argv` ran them)."""
    per_test = {
        SCENARIO + test: executed_lines(counters / folder_name(SCENARIO + test), build, source_root)
        for test in ids
    }
    return Coverage.build(digest, per_test)
