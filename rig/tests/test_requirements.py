"""Requirements traced to tests: the requirements file (`hilrig.requirements`) and the pytest
marker of hilrig's plugin in a project of its own (`pytester`): JUnit properties, the check both
ways (an unknown ID fails collection with one line, an ID no test names is listed uncovered),
each requirement's verdict, needs.json, and the same under pytest-xdist."""

from __future__ import annotations

import ast
import json
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from hilrig import requirements
from hilrig.errors import ConfigurationError

REQUIREMENTS = """
[[requirement]]
id = "CTRL_01"
title = "A velocity step settles"

[[requirement]]
id = "PROT_01"
title = "A silent encoder stops the drive"
text = "Within 20 cycles."
source = "README"

[[requirement]]
id = "PROT_02"
title = "The watchdog trips"

[[requirement]]
id = "NMT_01"
title = "NMT stop halts the PDOs"
"""

TESTS = """
import pytest

pytestmark = pytest.mark.requirement("CTRL_01")

@pytest.mark.requirement("PROT_01", "PROT_02")
def test_both():
    pass

@pytest.mark.requirement("PROT_02")
def test_fails():
    assert False

@pytest.mark.requirement("NMT_01")
@pytest.mark.skip(reason="not today")
def test_skipped():
    pass

def test_module_mark_only():
    pass

@pytest.mark.parametrize("n", [1, pytest.param(2, marks=pytest.mark.requirement("PROT_01"))])
def test_param(n):
    pass
"""


def _project(pytester: pytest.Pytester, tests: str = TESTS, ini: str = "") -> None:
    ini = f"addopts = --strict-markers\nhil_requirements = reqs/requirements.toml\n{ini}"
    pytester.makeini(f"[pytest]\n{ini}")
    (pytester.path / "reqs").mkdir()
    (pytester.path / "reqs" / "requirements.toml").write_text(REQUIREMENTS)
    pytester.makepyfile(test_things=tests)


def _properties(xml: Path) -> dict[str, list[str]]:
    found = {}
    for case in ET.parse(xml).getroot().iter("testcase"):
        found[case.get("name", "")] = [
            p.get("value", "") for p in case.iter("property") if p.get("name") == requirements.PROPERTY
        ]
    return found


@pytest.mark.parametrize("family", ["xunit1", "xunit2"])
def test_each_named_requirement_is_a_junit_property(pytester: pytest.Pytester, family: str) -> None:
    _project(pytester, ini=f"junit_family = {family}\n")
    result = pytester.runpytest("-p", "no:cacheprovider", "--junitxml=out.xml")
    result.assert_outcomes(passed=4, failed=1, skipped=1)
    assert _properties(pytester.path / "out.xml") == {
        "test_both": ["PROT_01", "PROT_02", "CTRL_01"],  # the closest marker first
        "test_fails": ["PROT_02", "CTRL_01"],
        "test_skipped": ["NMT_01", "CTRL_01"],
        "test_module_mark_only": ["CTRL_01"],
        "test_param[1]": ["CTRL_01"],
        "test_param[2]": ["PROT_01", "CTRL_01"],
    }
    assert "PytestWarning" not in result.stdout.str()


def test_the_summary_gives_each_requirements_verdict(pytester: pytest.Pytester) -> None:
    _project(pytester)
    result = pytester.runpytest("-p", "no:cacheprovider")
    result.stdout.re_match_lines(
        [
            r".* requirements \(reqs/requirements.toml\) .*",
            r"requirements: 1 of 4 verified by a passing test, 2 failed, 1 skipped$",
            r"    failed: CTRL_01 PROT_02$",
            r"    skipped: NMT_01$",
        ]
    )


def test_an_id_no_test_of_the_run_names_is_listed_uncovered(pytester: pytest.Pytester) -> None:
    _project(pytester)
    result = pytester.runpytest("-p", "no:cacheprovider", "-k", "test_both")
    result.assert_outcomes(passed=1, deselected=5)
    result.stdout.fnmatch_lines(
        ["requirements: 3 of 4 verified by a passing test, 1 uncovered", "    uncovered: NMT_01"]
    )


UNKNOWN = """
import pytest

@pytest.mark.requirement("CTRL_01", "CTRL_99")
def test_unknown():
    pass

def test_fine():
    pass
"""


def test_an_unknown_id_fails_collection_with_one_line(pytester: pytest.Pytester) -> None:
    _project(pytester, tests=UNKNOWN)
    result = pytester.runpytest("-p", "no:cacheprovider")
    assert result.ret == pytest.ExitCode.INTERRUPTED
    result.assert_outcomes(errors=1)
    expected = (
        "test_things.py::test_unknown: requirement CTRL_99 is not in reqs/requirements.toml: "
        "add it there or correct the test's marker"
    )
    out = result.stdout.str()
    assert expected in out.splitlines()
    assert "Traceback" not in out


@pytest.mark.parametrize(
    ("mark", "says"),
    [
        ("requirement()", "names no requirement"),
        ("requirement(7)", "a requirement ID is a string, got 7"),
        ('requirement("two words")', "'two words' is no requirement ID"),
        ('requirement(id="CTRL_01")', "takes IDs only, not id="),
    ],
)
def test_a_marker_naming_no_id_fails_collection(pytester: pytest.Pytester, mark: str, says: str) -> None:
    _project(pytester, tests=f"import pytest\n\n@pytest.mark.{mark}\ndef test_x():\n    pass\n")
    result = pytester.runpytest("-p", "no:cacheprovider")
    assert result.ret == pytest.ExitCode.INTERRUPTED
    assert says in result.stdout.str()


def test_the_check_holds_under_xdist_and_needs_json_comes_from_the_controller(
    pytester: pytest.Pytester,
) -> None:
    _project(pytester)
    pytester.makepyfile(test_bad=UNKNOWN)
    options = ["-n", "1", "--continue-on-collection-errors", "--hil-needs-json=out/needs.json"]
    result = pytester.runpytest("-p", "no:cacheprovider", *options)
    result.assert_outcomes(passed=4, failed=1, skipped=1, errors=1)
    unknown = "test_bad.py::test_unknown: requirement CTRL_99 is not in reqs/requirements.toml"
    assert unknown in result.stdout.str()
    result.stdout.fnmatch_lines(["requirements: 1 of 4 verified by a passing test, 2 failed, 1 skipped"])
    content = json.loads((pytester.path / "out" / "needs.json").read_text())
    needs = content["versions"][content["current_version"]]["needs"]
    assert {id_: need["status"] for id_, need in needs.items() if need["type"] == "req"} == {
        "CTRL_01": "failed",
        "PROT_01": "passed",
        "PROT_02": "failed",
        "NMT_01": "skipped",
    }
    assert needs["PROT_01"]["description"] == "Within 20 cycles."
    tests = {need["title"]: need for need in needs.values() if need["type"] == "test"}
    assert tests["test_things.py::test_both"]["links"] == ["PROT_01", "PROT_02", "CTRL_01"]
    assert tests["test_things.py::test_both"]["status"] == "passed"
    assert tests["test_things.py::test_fails"]["status"] == "failed"
    assert len(tests) == 6 and all(need["id"].startswith("TEST_") for need in tests.values())


def test_without_a_requirements_file_the_marker_is_exported_unchecked(pytester: pytest.Pytester) -> None:
    pytester.makeini("[pytest]\naddopts = --strict-markers\n")
    pytester.makepyfile(test_things=UNKNOWN)
    result = pytester.runpytest("-p", "no:cacheprovider", "--junitxml=out.xml")
    result.assert_outcomes(passed=2)
    assert _properties(pytester.path / "out.xml")["test_unknown"] == ["CTRL_01", "CTRL_99"]
    result.stdout.fnmatch_lines(["1 tests name requirements; no hil_requirements file checks them"])
    refused = pytester.runpytest("-p", "no:cacheprovider", "--hil-needs-json=n.json")
    assert refused.ret == pytest.ExitCode.USAGE_ERROR
    refused.stderr.fnmatch_lines(["ERROR: --hil-needs-json: name the requirements file with *"])


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("[[requirement]]\nid = 'A'\n", "each requirement needs an id and a title"),
        ("[[requirement]]\nid = 'A'\ntitle = 't'\n" * 2, "A is listed twice"),
        ("[[requirement]]\nid = 'A B'\ntitle = 't'\n", "'A B' is no requirement ID"),
        ("[[requirement]]\nid = 'A'\ntitle = 't'\nowner = 'x'\n", "unknown key 'owner'"),
        ("[requirements]\n", "unknown key 'requirements'"),
        ("", "no [[requirement]] table"),
        ("id = ", "not TOML"),
    ],
)
def test_a_bad_requirements_file_is_one_line_naming_it(tmp_path: Path, text: str, says: str) -> None:
    path = tmp_path / "requirements.toml"
    path.write_text(text)
    with pytest.raises(ConfigurationError, match=r".*") as caught:
        requirements.load(path)
    assert says in str(caught.value) and str(path) in str(caught.value)
    assert "\n" not in str(caught.value)


def test_a_bad_requirements_file_is_a_usage_error_of_the_run(pytester: pytest.Pytester) -> None:
    pytester.makeini("[pytest]\nhil_requirements = missing.toml\n")
    pytester.makepyfile(test_things="def test_x():\n    pass\n")
    result = pytester.runpytest("-p", "no:cacheprovider")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["ERROR: hil_requirements */missing.toml: No such file or directory"])


def test_the_ini_file_names_the_requirements_file_relative_to_itself(tmp_path: Path) -> None:
    (tmp_path / "pytest.ini").write_text("[pytest]\n# a comment\nhil_requirements = reqs/r.toml\n")
    assert requirements.ini_requirements(tmp_path / "pytest.ini") == tmp_path / "reqs" / "r.toml"
    (tmp_path / "pytest.ini").write_text("[pytest]\naddopts = -q\n")
    assert requirements.ini_requirements(tmp_path / "pytest.ini") is None


def _marked_ids(source: str) -> set[str]:
    """The IDs of every `pytest.mark.requirement(...)` call in a module's source."""
    found = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Call) and ast.unparse(node.func) == f"pytest.mark.{requirements.MARKER}":
            found |= {arg.value for arg in node.args if isinstance(arg, ast.Constant)}
    return found


def test_the_projects_requirements_are_each_named_by_a_scenario_and_nothing_else_is() -> None:
    root = Path(__file__).resolve().parents[2]
    path = requirements.ini_requirements(root / "pytest.ini")
    assert path is not None
    known = requirements.load(path)
    named = set()
    for scenario in (root / "tests").rglob("test_*.py"):
        named |= _marked_ids(scenario.read_text())
    assert sorted(set(known) - named) == [], "requirements no scenario names"
    assert sorted(named - set(known)) == [], "IDs the scenarios name that the file lacks"


def test_a_run_of_tests_that_name_no_requirement_says_nothing_of_them(pytester: pytest.Pytester) -> None:
    _project(pytester, tests="def test_plain():\n    pass\n")
    result = pytester.runpytest("-p", "no:cacheprovider")
    result.assert_outcomes(passed=1)
    assert "requirements" not in result.stdout.str()
