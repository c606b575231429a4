"""The board from a labgrid target (`--lg-env`, labgrid's own pytest option): its bus from the
target's `CANDriver` (`hilrig.lab`), its power from the target's power driver and its console from
its console driver, so the scenarios that run against a board on an interface (`--hil-interface`)
run unchanged on a farm's board.

The board is powered once per pytest session (off, then on, then the wait for its CANopen boot-up
message), and off again at the end; each scenario's share of the console lands in its folder as
`console.log`. labgrid is imported only when `--lg-env` (or $LG_ENV) is given.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import can
import pytest

from boardproto.cia301 import NmtState, heartbeat_cob_id
from hilrig.session.builder import BoardInterface

CONSOLE_LOG = "console.log"
CONSOLE_READ_S = 0.05
"""How long a console read waits for more bytes before the drain stops (nothing is timed by it)."""


def labgrid_env_given(config: pytest.Config) -> bool:
    """Whether this run's board comes from labgrid: `--lg-env` or $LG_ENV."""
    return bool(config.getoption("lg_env", None) or os.environ.get("LG_ENV"))


@dataclass
class LabgridBoard:
    """The target's board: how to open its bus, and its console (None: the target has none)."""

    interface: BoardInterface
    console: Any

    def save_console(self, path: Path) -> None:
        """Append what the console printed since the last call to `path`."""
        if self.console is None:
            return
        with path.open("ab") as out:
            while chunk := self.console.read(size=65536, timeout=CONSOLE_READ_S):
                out.write(chunk)


def wait_for_boot_up(bus: can.BusABC, node_id: int, timeout_s: float) -> None:
    """Block until the node's boot-up message (a hang guard of `timeout_s`, not a timing check)."""
    boot_up = heartbeat_cob_id(node_id)
    while True:
        frame = bus.recv(timeout=timeout_s)
        if frame is None:
            raise AssertionError(
                f"no boot-up message from node {node_id:#x} within {timeout_s:g} s of power on"
            )
        if frame.arbitration_id == boot_up and bytes(frame.data[:1]) == bytes([NmtState.INITIALISING]):
            return


def open_labgrid_board(target: Any, node_id: int, boot_timeout_s: float) -> Iterator[LabgridBoard]:
    """Power the target's board on (its power driver, if it has one) with its bus listening, wait
    for its boot-up, yield it; power it off afterwards."""
    from labgrid.exceptions import NoDriverFoundError

    driver = target.get_driver("CANDriver")
    try:
        power = target.get_driver("PowerProtocol")
    except NoDriverFoundError:
        power = None
    try:
        console = target.get_driver("ConsoleProtocol")
    except NoDriverFoundError:
        console = None
    interface = driver.board_interface()
    if power is not None:
        with driver.open_bus() as bus:
            power.off()
            power.on()
            wait_for_boot_up(bus, node_id, boot_timeout_s)
    try:
        yield LabgridBoard(interface=interface, console=console)
    finally:
        if power is not None:
            power.off()


__all__ = ["CONSOLE_LOG", "LabgridBoard", "labgrid_env_given", "open_labgrid_board"]
