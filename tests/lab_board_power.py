"""The "board" of the labgrid scenario and its power switch, for labgrid's ExternalPowerDriver:
`on STATE_DIR FIRMWARE NODE_ID PERIOD_US` starts the firmware free-running on vcan0 of the calling
namespace, detached (its output to STATE_DIR/board.log, its pid to STATE_DIR/board.pid), as power
makes a board boot; `off STATE_DIR` stops it with SIGTERM (the firmware prints its stop line) and
waits for it, as power off does. Off with nothing running is fine, as for a switch."""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
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
        exited = os.pidfd_open(pid)  # readable once the process exits (a zombie counts): no polling
    except ProcessLookupError:
        return
    try:
        signal.pidfd_send_signal(exited, signal.SIGTERM)  # the process waited on, whatever the pid
        ready, _, _ = select.select([exited], [], [], OFF_TIMEOUT_S)
        if ready:
            return
        signal.pidfd_send_signal(exited, signal.SIGKILL)
    except ProcessLookupError:  # it exited on its own meanwhile
        return
    finally:
        os.close(exited)
    sys.exit(f"the board (pid {pid}) did not stop on SIGTERM within {OFF_TIMEOUT_S:g} s: killed")


def main(argv: list[str]) -> None:
    if len(argv) == 5 and argv[0] == "on":
        power_on(Path(argv[1]), Path(argv[2]), int(argv[3], 0), int(argv[4]))
    elif len(argv) == 2 and argv[0] == "off":
        power_off(Path(argv[1]))
    else:
        sys.exit("usage: lab_board_power.py on STATE_DIR FIRMWARE NODE_ID PERIOD_US | off STATE_DIR")


if __name__ == "__main__":
    main(sys.argv[1:])
