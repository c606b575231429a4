"""Requirements and the tests that verify them: the project's requirements file, each
requirement's verdict from the tests of a run, and the traceability file (sphinx-needs'
`needs.json`).

    # requirements.toml (named by the pytest ini option `hil_requirements`)
    [[requirement]]
    id = "CTRL_01"                  # letters, digits, "_", "." and "-"
    title = "A velocity step settles within 2 % without more than 5 % overshoot"
    text = "..."                    # optional: the requirement in full
    source = "README: ..."          # optional: where it comes from

A test names what it verifies with `@pytest.mark.requirement("CTRL_01", ...)` (hilrig's pytest
plugin); each name becomes a JUnit property `requirement` of the test. The verdicts here come from
(test, requirements it names, outcome) triples, whichever run or XML files they were read from, so
the plugin (one pytest run) and tools/test-summary.py (every stage of `make test`) agree.

A base module: the standard library only.
"""

from __future__ import annotations

import hashlib
import json
import re
import textwrap
import tomllib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

from hilrig.errors import ConfigurationError
from hilrig.files import replacing

INI_OPTION = "hil_requirements"
"""The pytest ini option that names the requirements file (relative to the ini file)."""
MARKER = "requirement"
"""The pytest marker a test names its requirements with."""
PROPERTY = "requirement"
"""The JUnit property name of each requirement a test names (one property per requirement)."""
ID_PATTERN = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*")
"""What a requirement ID may be: what sphinx-needs, a JUnit reader and a shell take unquoted."""
_KEYS = frozenset({"id", "title", "text", "source"})

# A requirement's verdict in a run, the worst of its tests' outcomes first.
FAILED = "failed"
"""A test that names it failed (or errored)."""
PASSED = "passed"
"""Every test that names it and ran passed (skipped ones aside), at least one."""
SKIPPED = "skipped"
"""Every test that names it was skipped."""
UNCOVERED = "uncovered"
"""No test of the run names it."""
VERDICTS = (FAILED, PASSED, SKIPPED, UNCOVERED)


@dataclass(frozen=True)
class Requirement:
    id: str
    title: str
    text: str = ""
    source: str = ""


@dataclass(frozen=True)
class CaseResult:
    """One test of a run: its id (pytest's node id, or classname::name of a JUnit file), the
    requirements it names and its outcome (PASSED, FAILED or SKIPPED)."""

    name: str
    requirements: tuple[str, ...]
    outcome: str


@dataclass
class Coverage:
    """Each requirement's verdict and the tests that name it, in the file's order; `unknown`: IDs
    tests named that the file does not hold (collection refuses them: only from JUnit files)."""

    verdicts: dict[str, str] = field(default_factory=dict)
    tests: dict[str, list[CaseResult]] = field(default_factory=dict)
    unknown: dict[str, list[str]] = field(default_factory=dict)

    def ids(self, verdict: str) -> list[str]:
        return [id_ for id_, found in self.verdicts.items() if found == verdict]

    def summary(self, label: str = "requirements") -> str:
        """'requirements: 30 of 32 verified by a passing test, 1 failed, 1 uncovered'."""
        counts = {verdict: len(self.ids(verdict)) for verdict in VERDICTS}
        line = f"{label}: {counts[PASSED]} of {len(self.verdicts)} verified by a passing test"
        for verdict in (FAILED, SKIPPED, UNCOVERED):
            if counts[verdict]:
                line += f", {counts[verdict]} {verdict}"
        return line

    def lines(self, label: str = "requirements") -> list[str]:
        """The summary, then the IDs of each verdict other than PASSED (wrapped at 100 columns),
        then the unknown IDs with the tests that named them."""
        lines = [self.summary(label)]
        for verdict in (FAILED, SKIPPED, UNCOVERED):
            if found := self.ids(verdict):
                lines += textwrap.wrap(
                    " ".join(found), width=100, initial_indent=f"    {verdict}: ", subsequent_indent=" " * 8
                )
        for id_, names in self.unknown.items():
            lines.append(f"    not in the requirements file: {id_} (named by {', '.join(names)})")
        return lines


def check_id(value: object) -> str | None:
    """Why `value` is no requirement ID (None: it is one)."""
    if not isinstance(value, str):
        return f"a requirement ID is a string, got {value!r}"
    if not ID_PATTERN.fullmatch(value):
        return f"{value!r} is no requirement ID (letters, digits, '_', '.' and '-')"
    return None


def load(path: Path) -> dict[str, Requirement]:
    """The requirements of a file, by ID in the file's order; a ConfigurationError that names the
    file and what to fix otherwise."""
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as error:
        raise ConfigurationError(f"{INI_OPTION} {path}: {error.strerror or error}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as error:
        raise ConfigurationError(f"{INI_OPTION} {path}: not TOML: {error}") from None
    extra = sorted(set(data) - {"requirement"})
    if extra:
        raise ConfigurationError(f"{path}: unknown key {extra[0]!r}: the file holds [[requirement]] tables")
    entries = data.get("requirement", [])
    if not isinstance(entries, list) or not entries:
        raise ConfigurationError(f"{path}: no [[requirement]] table (each with an id and a title)")
    found: dict[str, Requirement] = {}
    for number, entry in enumerate(entries, 1):
        where = f"{path}: requirement {number}"
        if not isinstance(entry, dict):
            raise ConfigurationError(f"{where}: expected a [[requirement]] table")
        unknown = sorted(set(entry) - _KEYS)
        if unknown:
            raise ConfigurationError(f"{where}: unknown key {unknown[0]!r} (keys: id, title, text, source)")
        if "id" not in entry or not entry.get("title"):
            raise ConfigurationError(f"{where}: each requirement needs an id and a title")
        problem = check_id(entry["id"])
        if problem:
            raise ConfigurationError(f"{where}: {problem}")
        if not all(isinstance(entry.get(key, ""), str) for key in _KEYS):
            raise ConfigurationError(f"{where}: title, text and source are strings")
        if entry["id"] in found:
            raise ConfigurationError(f"{where}: {entry['id']} is listed twice")
        found[entry["id"]] = Requirement(
            id=entry["id"], title=entry["title"], text=entry.get("text", ""), source=entry.get("source", "")
        )
    return found


def ini_requirements(ini: Path) -> Path | None:
    """The requirements file a pytest ini file names (`hil_requirements`, relative to it), read
    as pytest reads it; None where it names none."""
    import iniconfig  # pytest's own ini parser (a dependency of pytest)

    parsed = iniconfig.IniConfig(ini)
    value = parsed.get("pytest", INI_OPTION, default="").strip() if "pytest" in parsed else ""
    return (ini.parent / value).resolve() if value else None


def coverage(requirements: Mapping[str, Requirement], results: Iterable[CaseResult]) -> Coverage:
    """Each requirement's verdict from the run's tests (see VERDICTS)."""
    found = Coverage(verdicts=dict.fromkeys(requirements, UNCOVERED), tests={id_: [] for id_ in requirements})
    for result in results:
        for id_ in dict.fromkeys(result.requirements):
            if id_ not in requirements:
                found.unknown.setdefault(id_, []).append(result.name)
                continue
            found.tests[id_].append(result)
    for id_, tests in found.tests.items():
        outcomes = {test.outcome for test in tests}
        for verdict in (FAILED, PASSED, SKIPPED):
            if verdict in outcomes:
                found.verdicts[id_] = verdict
                break
    return found


def _test_need_id(name: str) -> str:
    """A test's need ID: stable across runs, in sphinx-needs' default ID alphabet."""
    return "TEST_" + hashlib.sha1(name.encode()).hexdigest()[:10].upper()


def needs_json(
    requirements: Mapping[str, Requirement], results: Iterable[CaseResult], project: str
) -> dict[str, object]:
    """The traceability of a run as sphinx-needs' needs.json: each requirement a need of type
    `req` whose status is its verdict, each test naming a requirement a need of type `test`
    whose status is its outcome and whose links are the requirements it verifies (sphinx-needs'
    `needimport` reads it; its back links then list each requirement's tests)."""
    results = list(results)
    found = coverage(requirements, results)
    needs: dict[str, dict[str, object]] = {}
    for id_, requirement in requirements.items():
        needs[id_] = {
            "id": id_,
            "type": "req",
            "type_name": "Requirement",
            "title": requirement.title,
            "description": requirement.text,
            "status": found.verdicts[id_],
            "links": [],
            "tags": [],
            "source": requirement.source,
        }
    for result in results:
        if not result.requirements:
            continue
        need = _test_need_id(result.name)
        needs[need] = {
            "id": need,
            "type": "test",
            "type_name": "Test Case",
            "title": result.name,
            "description": "",
            "status": result.outcome,
            "links": list(dict.fromkeys(result.requirements)),
            "tags": [],
        }
    created = datetime.now(UTC).isoformat(timespec="seconds")
    version = {"created": created, "needs": needs, "needs_amount": len(needs)}
    return {"created": created, "current_version": "", "project": project, "versions": {"": version}}


def write_needs_json(path: Path, content: Mapping[str, object]) -> None:
    """Written whole (`hilrig.files.replacing`): a CI job never archives half a file."""
    with replacing(path) as temporary:
        temporary.write_text(json.dumps(content, indent=2) + "\n", encoding="utf-8")


__all__ = [
    "FAILED",
    "ID_PATTERN",
    "INI_OPTION",
    "MARKER",
    "PASSED",
    "PROPERTY",
    "SKIPPED",
    "UNCOVERED",
    "VERDICTS",
    "CaseResult",
    "Coverage",
    "Requirement",
    "check_id",
    "coverage",
    "ini_requirements",
    "load",
    "needs_json",
    "write_needs_json",
]
