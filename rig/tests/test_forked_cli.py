"""`hilrig.cli.forked.run`: a command forked from the warm server answers as the console script
does (exit code, stdout, stderr), in the caller's directory and environment."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from hilrig.cli import forked

CONSOLE_SCRIPT = Path(sys.executable).parent / "hilrig"


def console(*argv: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(CONSOLE_SCRIPT), *argv], capture_output=True, text=True, check=False, cwd=cwd)


@pytest.mark.parametrize(
    "argv",
    [
        ["fields", "--kind", "parameter"],  # a table on stdout, exit 0
        ["get"],  # a usage error: exit 2, one line on stderr
        ["nonsense-command"],
        ["dbc", "--node-id", "0x200", "-o", "x.dbc"],  # out of range: the CLI's refusal
    ],
)
def test_a_forked_command_answers_as_the_console_script(argv: list[str], tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    forked_result = forked.run(argv, timeout_s=120)
    script_result = console(*argv, cwd=tmp_path)
    assert (forked_result.returncode, forked_result.stdout, forked_result.stderr) == (
        script_result.returncode,
        script_result.stdout,
        script_result.stderr,
    )


def test_it_writes_where_the_caller_is_and_sees_the_callers_environment(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("NO_COLOR", "1")
    done = forked.run(["dbc", "-o", "board.dbc"], timeout_s=120)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "board.dbc").read_text().startswith("VERSION")
    shown = forked.run(["--version"], env={"PATH": "/usr/bin"}, timeout_s=120)
    assert shown.returncode == 0 and shown.stdout.startswith("hilrig ")


def test_a_command_past_its_hang_guard_is_killed() -> None:
    with pytest.raises(subprocess.TimeoutExpired):
        forked.run(["monitor", "-i", "virtual", "-c", "forked-silent"], timeout_s=1)
