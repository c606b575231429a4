"""Each board's firmware (the joint's and the head's, as the scenarios run them) on its command
line: --help opens with the board's own description and names the program, a bad option or a
period outside the table's [node] range is one line on stderr naming the program and pointing to
--help, with the usage exit code. The program's name is the board's, not its file's: a copied or
renamed executable (a deployed image, a test folder) still says which firmware it is.
"""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from hilrig import resources
from hilrig.cli import EXIT_USAGE
from hilrig.table import RigTable

pytestmark = pytest.mark.bus

BOARDS = {
    # program name, where the scenarios find it, its table, its --help's first words
    "joint-firmware": (
        lambda: resources.DEFAULT_FIRMWARE,
        resources.DEFAULT_TABLE,
        "Firmware of the demo series-elastic joint",
    ),
    "head-firmware": (
        lambda: resources.HEAD_FIRMWARE,
        resources.HEAD_TABLE,
        "Firmware of the robot head module (IMU, RGB LED, current-limited power rail, battery)",
    ),
}


def renamed_copy(program: str, folder: Path) -> Path:
    """The board's firmware under a file name that is not its program's."""
    executable, _, _ = BOARDS[program]
    copy = folder / "board.img"
    shutil.copy2(executable(), copy)
    return copy


def run(executable: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(executable), *args], capture_output=True, text=True, timeout=30, check=False)


@pytest.mark.parametrize("program", sorted(BOARDS))
def test_help_names_the_board_and_the_program(program: str, tmp_path: Path) -> None:
    _, _, description = BOARDS[program]
    done = run(renamed_copy(program, tmp_path), "--help")
    assert done.returncode == 0, done.stderr
    first_line = done.stdout.splitlines()[0]
    assert first_line == f"{description}, a CANopen (CiA 301) node on SocketCAN.", first_line
    assert f"Usage: {program} [OPTIONS]" in done.stdout, done.stdout[:600]
    assert done.stderr == ""


@pytest.mark.parametrize("program", sorted(BOARDS))
def test_an_unknown_option_is_one_line_naming_the_program(program: str, tmp_path: Path) -> None:
    done = run(renamed_copy(program, tmp_path), "--no-such-option")
    assert done.returncode == EXIT_USAGE  # the firmware's kExitUsage, the rig's CLI's convention too
    assert done.stdout == ""
    assert done.stderr == (
        f"{program}: The following argument was not expected: --no-such-option (see {program} --help)\n"
    )


@pytest.mark.parametrize("program", sorted(BOARDS))
def test_a_period_outside_the_tables_range_is_refused_with_the_range(program: str, tmp_path: Path) -> None:
    _, table, _ = BOARDS[program]
    node = RigTable.load(table).board.node
    copy = renamed_copy(program, tmp_path)
    for period in (node.period_us_min - 1, node.period_us_max + 1):
        done = run(copy, "--period-us", str(period))
        assert done.returncode == EXIT_USAGE
        assert done.stderr == (
            f"{program}: --period-us: Value {period} not in range {node.period_us_min} to "
            f"{node.period_us_max} (see {program} --help)\n"
        )


@pytest.mark.parametrize("program", sorted(BOARDS))
def test_a_node_id_outside_cia301s_range_is_refused(program: str, tmp_path: Path) -> None:
    copy = renamed_copy(program, tmp_path)
    for node_id in ("0", "128", "0xFE", "seven"):
        done = run(copy, "--node-id", node_id)
        assert done.returncode == EXIT_USAGE, node_id
        assert done.stderr.startswith(f"{program}: --node-id: node id {node_id} is not 1..127 or 0xFF"), (
            done.stderr
        )
