"""The figures the README and the manual show for `make run`, checked against a real run.

`make run` is `hilrig sim` with the demo's default profile (tools/run-demo.py); its summary's
figures are simulation results, the same on any machine, so the docs' sample of them can be
exact: this runs the demo as `make run` does and compares the lines each marked block shows
with the ones the run printed. A change to the firmware, the plant or the demo that moves a
figure fails here until the docs say what the run now prints.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest
from conftest import REPO

pytestmark = pytest.mark.bus

HILRIG = str(REPO / ".venv" / "bin" / "hilrig")
MARKER = "<!-- what make run prints"
DOCUMENTS = [REPO / "README.md", REPO / "docs" / "getting-started.md"]
# A hang guard for a slow guest, not a timing check.
RUN_TIMEOUT_S = 600


def shown_blocks(path: Path) -> list[list[str]]:
    """The lines of each ```text block that follows the marker in the document."""
    blocks = re.findall(rf"{re.escape(MARKER)}[^\n]*\n```text\n(.*?)```", path.read_text(), re.S)
    return [block.splitlines() for block in blocks]


def test_every_document_shows_the_demo_summary_once() -> None:
    for path in DOCUMENTS:
        assert len(shown_blocks(path)) == 1, f"{path}: one block after {MARKER!r}"


def test_the_demo_summary_the_docs_show_is_what_make_run_prints(scenario_dir: Path) -> None:
    done = subprocess.run(
        [HILRIG, "sim", "--out", str(scenario_dir / "demo"), "--no-trace"],
        capture_output=True,
        text=True,
        timeout=RUN_TIMEOUT_S,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    printed = done.stdout.splitlines()
    for path in DOCUMENTS:
        (shown,) = shown_blocks(path)
        labels = [line[:26] for line in shown]
        actual = [line for line in printed if line[:26] in labels]
        assert shown == actual, (
            f"{path.relative_to(REPO)} shows a summary `make run` no longer prints; it prints:\n"
            + "\n".join(actual)
        )
