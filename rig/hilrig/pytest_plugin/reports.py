"""What a failed scenario leaves for a reviewer (part of hilrig's pytest plugin).

* Where to look: a scenario's fixtures name its evidence (`request.node.hil_evidence`: its trace,
  its bus log); a failure shows it in its report and in a list at the end of the run.
* A picture with every failure: a failing `hilrig.expect` check draws its PNG
  (`ScenarioAssertion.pictures`); the plugin names it in the report, attaches it to the JUnit XML
  as `[[ATTACHMENT|/abs/path.png]]` in the test's system-out (the convention Jenkins' and GitLab's
  JUnit readers follow; pytest writes system-out for failures with `junit_logging = system-out`),
  and lists it at the end of the run.
* The last good run: with `--hil-baseline DIR`, a scenario that passes keeps its trace as
  DIR/<test>.rrd; a later failure of that scenario prints the `hilrig diff` command that shows
  what changed. A scenario says which trace is its own by setting `request.node.hil_trace`
  (the rig's fixtures do).
"""

from __future__ import annotations

import re
import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest

from hilrig.files import replacing

ATTACHMENT = "[[ATTACHMENT|{path}]]"
"""How a JUnit reader finds a file to attach in a test's system-out."""
_SUMMARY = pytest.StashKey[list[str]]()
_EVIDENCE = pytest.StashKey[list[str]]()
_CALL_PASSED = pytest.StashKey[bool]()


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("hilrig", "hilrig scenarios")
    group.addoption(
        "--hil-baseline",
        metavar="DIR",
        default=None,
        help="keep each passing scenario's trace as DIR/<test>.rrd; a failing one prints the "
        "`hilrig diff` command against it",
    )


def pytest_configure(config: pytest.Config) -> None:
    config.stash[_SUMMARY] = []
    config.stash[_EVIDENCE] = []


def baseline_path(folder: Path, nodeid: str, suffix: str = ".rrd") -> Path:
    """DIR/<test>.rrd for a test id ('tests/test_joint.py::test_step[a]' -> test_joint.test_step_a_.rrd)."""
    name = nodeid.rsplit("/", 1)[-1].replace(".py::", ".").replace("::", ".")
    return folder / (re.sub(r"[^A-Za-z0-9_.-]+", "_", name) + suffix)


def _keep(trace: Path, kept: Path) -> None:
    """Copy whole: to a temporary file beside, renamed when complete."""
    with replacing(kept) as temporary:
        shutil.copyfile(trace, temporary)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Iterator[None]:
    outcome = yield
    report: pytest.TestReport = outcome.get_result()
    summary = item.config.stash[_SUMMARY]
    folder = item.config.getoption("hil_baseline")
    trace: Path | None = getattr(item, "hil_trace", None)
    evidence: str | None = getattr(item, "hil_evidence", None)
    if report.failed and evidence:
        report.sections.append(("scenario evidence", evidence))
        item.config.stash[_EVIDENCE].append(f"FAILED {item.nodeid}: {evidence}")
    if report.when == "call":
        item.stash[_CALL_PASSED] = report.passed
    if report.failed and call.excinfo is not None:
        pictures = getattr(call.excinfo.value, "pictures", ())
        if pictures:
            text = "".join(ATTACHMENT.format(path=Path(p).resolve()) + "\n" for p in pictures)
            report.sections.append((f"Captured stdout {report.when}", text))  # shown with the failure
            item.add_report_section(report.when, "stdout", text)  # in the JUnit XML's system-out
            summary += [f"{item.nodeid}: picture {Path(p)}" for p in pictures]
        if folder and trace is not None and report.when == "call":
            kept = baseline_path(Path(folder), item.nodeid)
            if kept.is_file():
                command = f"hilrig diff {kept} {trace}"
                report.sections.append(("what changed since the last good run", command))
                summary.append(f"{item.nodeid}: what changed: {command}")
    # The trace is whole once the scenario's session closed: after teardown.
    passed = report.when == "teardown" and report.passed and item.stash.get(_CALL_PASSED, False)
    if passed and folder and trace is not None and trace.is_file():
        _keep(trace, baseline_path(Path(folder), item.nodeid))


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    evidence = terminalreporter.config.stash.get(_EVIDENCE, [])
    if evidence:
        terminalreporter.section("failed scenarios: where to look")
        for line in evidence:
            terminalreporter.line(line)
    lines = terminalreporter.config.stash.get(_SUMMARY, [])
    if lines:
        terminalreporter.section("failed scenarios: pictures and comparisons")
        for line in lines:
            terminalreporter.line(line)
