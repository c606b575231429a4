"""Comments say what and why: no measured figure and no issue number in the tree's comments
(tools/comment_figures.py), and the check's rules on small examples, so it cannot pass by
finding nothing."""

from __future__ import annotations

from pathlib import Path

import pytest
from tool_loader import load_tool

check = load_tool("comment_figures")


def findings_in(tmp_path: Path, name: str, source: str) -> list[str]:
    path = tmp_path / name
    path.write_text(source)
    return [finding.what.split(" (")[0] for finding in check.scan_file(path)]


def test_the_trees_comments_carry_no_measurement_and_no_issue_number() -> None:
    files = check.scanned_files()
    assert check.REPO / "rig" / "hilrig" / "wire" / "_wire.c" in files
    assert check.REPO / "firmware" / "canopen" / "Node.cpp" in files
    findings = check.scan(files)
    assert not findings, "\n".join(map(str, findings))


@pytest.mark.parametrize(
    ("name", "source"),
    [
        ("a.py", "# 3401 cycles took 8.5 s without polling\nx = 1\n"),
        ("b.py", 'RATE = 2\n"""The exchange ran at 1700 cycles/s, blocking."""\n'),
        ("c.py", 'def f() -> None:\n    """Twice as fast: measured 190 us against 370 us."""\n'),
        ("d.cpp", "// One RK4 step\n// took 5 ms of a cycle.\nint x;\n"),
        ("e.c", "/* a read costs ~30 us in the VM */\nint x;\n"),
    ],
)
def test_a_measurement_in_a_comment_is_found(tmp_path: Path, name: str, source: str) -> None:
    assert findings_in(tmp_path, name, source) == ["a measurement in a comment"]


@pytest.mark.parametrize(
    ("name", "source"),
    [("a.py", "# Fixed in issue 20: counted in 64 bits.\n"), ("b.cpp", "// Issue 43's bad inputs\nint x;\n")],
)
def test_an_issue_number_in_a_comment_is_found(tmp_path: Path, name: str, source: str) -> None:
    assert findings_in(tmp_path, name, source) == ["an issue number in a comment"]


@pytest.mark.parametrize(
    "source",
    [
        "# A hang guard of 300 s, not a timing check: a slow guest took longer.\n",
        "# Goal: the firmware at least 3x faster (median).\n",
        "TIMEOUT_S = 5.0  # the wait's bound\n",
        "# Measured from the frames' own timestamps.\n",
        "# python-can #1992: the header is local time.\n",
        'x = "took 8.5 s"  # a string, not a comment\n',
    ],
)
def test_bounds_goals_and_plain_words_are_not_findings(tmp_path: Path, source: str) -> None:
    assert findings_in(tmp_path, "a.py", source) == []
