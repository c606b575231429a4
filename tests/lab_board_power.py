"""The "board" of the labgrid scenario and its power switch, for labgrid's ExternalPowerDriver:
`on STATE_DIR FIRMWARE NODE_ID PERIOD_US` starts the firmware free-running on vcan0 of the calling
namespace, detached (its output to STATE_DIR/board.log, its pid to STATE_DIR/board.pid), as power
makes a board boot; `off STATE_DIR` stops it with SIGTERM (the firmware prints its stop line) and
waits for it, as power off does. Off with nothing running is fine, as for a switch."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from hilrig.engine.timing import TimingMode
from hilrig.session.firmware import firmware_argv

OFF_TIMEOUT_S = 30.0
"""Hang guard for the firmware to exit on SIGTERM (ASan build in the emulated VM), not a timing check."""


def power_on(state: Path, firmware: Path, node_id: int, period_us: int) -> None:
    state.mkdir(parents=True, exist_ok=True)
    argv = firmware_argv(firmware, "vcan0", node_id, period_us, mode=TimingMode.REALTIME)
    with (state / "board.log").open("ab") as log:
        process = subprocess.Popen(
            argv, stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT, start_new_session=True
        )
    (state / "board.pid").write_text(f"{process.pid}\n")


def power_off(state: Path) -> None:
    pid_file = state / "board.pid"
    if not pid_file.exists():
        return
    pid = int(pid_file.read_text())
    pid_file.unlink()
    try:
        os.kill(pid, signal.SIGTERM)
    except ProcessLookupError:
        return
    deadline = time.monotonic() + OFF_TIMEOUT_S
    while time.monotonic() < deadline:
        if not _alive(pid):
            return
        time.sleep(0.05)
    os.kill(pid, signal.SIGKILL)
    sys.exit(f"the board (pid {pid}) did not stop on SIGTERM within {OFF_TIMEOUT_S:g} s: killed")


def _alive(pid: int) -> bool:
    """Whether the process runs (not our child: an exited one may linger as a zombie until init
    reaps it)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rpartition(")")[2].split()[0] != "Z"


def main(argv: list[str]) -> None:
    if len(argv) == 5 and argv[0] == "on":
        power_on(Path(argv[1]), Path(argv[2]), int(argv[3], 0), int(argv[4]))
    elif len(argv) == 2 and argv[0] == "off":
        power_off(Path(argv[1]))
    else:
        sys.exit("usage: lab_board_power.py on STATE_DIR FIRMWARE NODE_ID PERIOD_US | off STATE_DIR")


if __name__ == "__main__":
    main(sys.argv[1:])
