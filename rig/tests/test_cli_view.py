"""`hilrig view`: a saved trace in the viewer with a dashboard (the viewer itself is started in
rig/tests/test_web_viewer.py through the same `open_trace`)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from hilrig.cli import main
from hilrig.trace import blueprint_names

REPO = Path(__file__).resolve().parents[2]


def test_list_names_every_dashboard(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["view", "--list"]) == 0
    assert capsys.readouterr().out.split() == list(blueprint_names())
    assert {"overview", "tuning", "thermal", "faults"} <= set(blueprint_names())


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        ([], "name the trace to open"),
        (["missing.rrd"], "trace missing.rrd does not exist"),
        (["{rrd}", "--dashboard", "tunning"], "did you mean 'tuning'"),
        (["{log}"], "expected a Rerun recording (.rrd)"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(
    argv: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rrd, log = tmp_path / "t.rrd", tmp_path / "bus.log"
    rrd.write_bytes(b"")
    log.write_text("")
    code = main(["view", *(a.format(rrd=rrd, log=log) for a in argv)])
    err = capsys.readouterr().err
    assert code == 2
    assert len(err.splitlines()) == 1 and message in err, err


def test_the_older_spelling_still_works() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "dashboards", "--list"], capture_output=True, text=True, cwd=REPO, check=False
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == list(blueprint_names())
