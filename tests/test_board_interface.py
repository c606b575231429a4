"""The manual's command (docs/bring-up.md) that points the scenarios at a real board, run for real.

The firmware stands in for the board: it boots on its own, free-running (`--mode free`), on an
interface the rig did not make, as a board on can0 would. pytest is then started the way the
docs say, `--hil-interface socketcan --hil-channel vcan0` (plus `--hil-physics`: this board
takes its sensors from the bus), and runs the two-worlds file unchanged: the rig opens that
interface and starts no firmware, the real-time scenarios pass against the board, the lockstep
one is skipped with its reason, and the evidence lands where the docs say.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import NODE_ID, REALTIME_FIRMWARE_PERIOD_US, REPO, stop_summary

from hilrig.engine.timing import TimingMode
from hilrig.session.firmware import Firmware
from hilrig.session.netns import PrivateBus

pytestmark = [pytest.mark.bus, pytest.mark.slow, pytest.mark.realtime]

INNER_RUN_TIMEOUT_S = 540.0
"""Hang guard for the inner pytest (below pytest.ini's 600 s, so its output is not lost)."""


@pytest.mark.requirement("CTRL_04")
def test_readme_command_runs_the_realtime_scenarios_against_a_board_on_an_interface(
    private_bus: PrivateBus, scenario_dir: Path
) -> None:
    board = Firmware(
        private_bus,
        node_id=NODE_ID,
        log_path=scenario_dir / "board.log",
        mode=TimingMode.REALTIME,
        period_us=REALTIME_FIRMWARE_PERIOD_US,
    )
    board.start()
    inner_out = scenario_dir / "out"
    readme_command = [
        sys.executable, "-m", "pytest", "tests/test_two_worlds.py",
        "--hil-interface", "socketcan", "--hil-channel", private_bus.channel, "--hil-physics",
    ]  # fmt: skip
    try:
        inner = subprocess.run(
            private_bus.command([*readme_command, "-p", "no:cacheprovider", "-q", "-rs"]),
            cwd=REPO,
            env={**os.environ, "HIL_OUT_DIR": str(inner_out)},
            capture_output=True,
            text=True,
            timeout=INNER_RUN_TIMEOUT_S,
        )
        board.check()  # the board is still running: the scenarios talked to it, did not restart it
    finally:
        board.stop()
    output = inner.stdout + inner.stderr
    assert inner.returncode == 0, f"the documented command failed (exit {inner.returncode}):\n{output}"
    assert re.search(r"\b2 passed, 1 skipped\b", output), output
    assert "a lockstep scenario needs the firmware on a private bus" in output, output
    for test in ("test_velocity_hold_realtime", "test_observe_and_command_realtime_without_physics"):
        evidence = inner_out / "scenarios" / test
        assert (evidence / "bus.log").stat().st_size > 0, f"no bus log in {evidence}"
        assert (evidence / "trace.rrd").stat().st_size > 0, f"no trace in {evidence}"
        assert not (evidence / "firmware.log").exists(), f"the rig started a firmware in {evidence}"
    counters = stop_summary(board)  # what the board itself counted, on its own clock
    assert counters["frames received"] > 0 and counters["cycles"] > 0, counters
    print(f"\n{output.strip().splitlines()[-1]}; the board: {counters}")
