"""Which test verifies which requirement (part of hilrig's pytest plugin).

    # pytest.ini
    [pytest]
    hil_requirements = requirements.toml     # IDs and titles (hilrig.requirements)

    @pytest.mark.requirement("PROT_01", "EMCY_02")
    def test_silent_encoder_goes_to_safe_state_with_emcy(make_scenario): ...

* Each ID a test names (on the function, its class, its module's `pytestmark` or a
  `pytest.param(..., marks=...)`) is a JUnit property `requirement` of the test
  (`<property name="requirement" value="PROT_01"/>`), for xunit1 and xunit2 alike.
* Checked both ways against the file: a test naming an ID the file does not hold, or a marker
  naming none, fails its module's collection with one line; a run in which a test names a
  requirement ends with each requirement's verdict (`hilrig.requirements.VERDICTS`), the
  uncovered ones (no test of the run names them) listed by ID.
* `--hil-needs-json PATH` writes the run's traceability as sphinx-needs' needs.json.

Without `hil_requirements` the marker still becomes JUnit properties, unchecked.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import pytest

from hilrig import requirements
from hilrig.errors import ConfigurationError


@dataclass
class _State:
    known: dict[str, requirements.Requirement] | None
    """The requirements file's, by ID (None: no file named)."""
    spelled: str
    """The file as the ini option names it (what a message says)."""
    results: dict[str, requirements.CaseResult] = field(default_factory=dict)
    """Each finished test of this run that names a requirement, by node id."""


_STATE = pytest.StashKey[_State]()


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addini(
        requirements.INI_OPTION,
        "the requirements file (TOML: [[requirement]] id, title) the tests' requirement markers name",
    )
    group = parser.getgroup("hilrig", "hilrig scenarios")
    group.addoption(
        "--hil-needs-json",
        metavar="PATH",
        default=None,
        help="write the run's traceability (each requirement, the tests naming it, their outcomes) "
        "as sphinx-needs' needs.json; needs hil_requirements",
    )


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        f"{requirements.MARKER}(*ids): the requirements this test verifies "
        f"(IDs of {requirements.INI_OPTION})",
    )
    spelled = str(config.getini(requirements.INI_OPTION) or "").strip()
    known = None
    if spelled:
        base = config.inipath.parent if config.inipath is not None else config.rootpath
        try:
            known = requirements.load((base / spelled).resolve())
        except ConfigurationError as error:
            raise pytest.UsageError(str(error)) from None
    elif config.getoption("hil_needs_json"):
        raise pytest.UsageError(
            f"--hil-needs-json: name the requirements file with {requirements.INI_OPTION} in the ini file"
        )
    state = _State(known=known, spelled=spelled)
    config.stash[_STATE] = state
    config.pluginmanager.register(_Run(config, state), "hilrig-requirements-run")


def _named(item: pytest.Item) -> tuple[list[str], str | None]:
    """The IDs the item's requirement markers name, in order, and what is wrong with them."""
    ids: list[str] = []
    for mark in item.iter_markers(requirements.MARKER):
        if mark.kwargs:
            return ids, f"@pytest.mark.{requirements.MARKER} takes IDs only, not {sorted(mark.kwargs)[0]}="
        if not mark.args:
            return ids, f'@pytest.mark.{requirements.MARKER}() names no requirement: give its IDs ("ID", ...)'
        for value in mark.args:
            problem = requirements.check_id(value)
            if problem:
                return ids, problem
            ids.append(value)
    return list(dict.fromkeys(ids)), None


def _problem(item: pytest.Item, state: _State) -> str | None:
    ids, problem = _named(item)
    if problem:
        return f"{item.nodeid}: {problem}"
    if state.known is not None:
        for id_ in ids:
            if id_ not in state.known:
                return (
                    f"{item.nodeid}: requirement {id_} is not in {state.spelled}: add it there or "
                    "correct the test's marker"
                )
    return None


@pytest.hookimpl(wrapper=True)
def pytest_make_collect_report(collector: pytest.Collector) -> pytest.CollectReport:
    """A module (or class) whose tests name an unknown requirement fails to collect, with one
    line: in a worker of pytest-xdist as in a plain run."""
    report: pytest.CollectReport = yield
    state = collector.config.stash.get(_STATE, None)
    if state is None or not report.passed:
        return report
    problems = [p for node in report.result if isinstance(node, pytest.Item) and (p := _problem(node, state))]
    if problems:
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        report.outcome = "failed"
        report.longrepr = problems[0] + more
        report.result = []
    return report


def pytest_itemcollected(item: pytest.Item) -> None:
    ids, _ = _named(item)
    item.user_properties.extend((requirements.PROPERTY, id_) for id_ in ids)


def _is_worker(config: pytest.Config) -> bool:
    """A pytest-xdist worker: its controller sees every report and writes the summaries."""
    return hasattr(config, "workerinput")


class _Run:
    """The run's outcomes of the tests that name requirements (registered per config: a report
    hook gets no config), its needs.json and its summary."""

    def __init__(self, config: pytest.Config, state: _State) -> None:
        self.config = config
        self.state = state

    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        """Each test's outcome over its phases: failed if any phase failed, skipped if it was
        skipped, passed if its call passed (an xfail counts as skipped: it verifies nothing)."""
        named = tuple(str(value) for name, value in report.user_properties if name == requirements.PROPERTY)
        if not named:
            return
        previous = self.state.results.get(report.nodeid)
        outcome = previous.outcome if previous is not None else ""
        if report.failed:
            outcome = requirements.FAILED
        elif report.skipped and outcome != requirements.FAILED:
            outcome = requirements.SKIPPED
        elif report.when == "call" and report.passed and not outcome:
            outcome = requirements.PASSED
        self.state.results[report.nodeid] = requirements.CaseResult(report.nodeid, named, outcome)

    def results(self) -> list[requirements.CaseResult]:
        return [result for result in self.state.results.values() if result.outcome]

    def pytest_sessionfinish(self, session: pytest.Session) -> None:
        target = self.config.getoption("hil_needs_json")
        if self.state.known is None or not target or _is_worker(self.config):
            return
        content = requirements.needs_json(self.state.known, self.results(), self.config.rootpath.name)
        requirements.write_needs_json(Path(target), content)

    def pytest_terminal_summary(self, terminalreporter: pytest.TerminalReporter) -> None:
        if _is_worker(self.config):
            return
        results = self.results()
        target = self.config.getoption("hil_needs_json")
        if not results and not target:
            return  # a run of tests that name no requirement (unit tests): nothing to say
        if self.state.known is None:
            terminalreporter.section("requirements")
            terminalreporter.line(
                f"{len(results)} tests name requirements; no {requirements.INI_OPTION} file checks them"
            )
            return
        terminalreporter.section(f"requirements ({self.state.spelled})")
        for line in requirements.coverage(self.state.known, results).lines():
            terminalreporter.line(line)
        if target:
            terminalreporter.line(f"traceability: {target} (sphinx-needs needs.json)")
