"""The firmware's SocketCAN port on a real bus: its googletest (firmware/platform/linux/
SocketCanPortTest.cpp: the kernel acceptance filter, the batched receive, the node's wiring), run
on this scenario's private vcan0. The C++ unit stage has no bus and skips every test there; here
none may skip. The build beside the firmware the scenarios run: build/release's under user-mode
Linux (ASan cannot run there; the Makefile builds it with -DHIL_PORT_TESTS=ON), build/'s natively."""

from __future__ import annotations

import os
import re
import subprocess

import pytest

from hilrig.pytest_plugin.board import HilBoard
from hilrig.session.netns import PrivateBus

pytestmark = pytest.mark.bus


def test_the_socketcan_port_tests_pass_on_a_real_bus(private_bus: PrivateBus, hil_board: HilBoard) -> None:
    tests = hil_board.firmware.parent / "fw_linux_tests"
    if not tests.exists():
        pytest.fail(
            f"no {tests}: `make build` builds it (a build/release configured before it existed: "
            "cmake -S . -B build/release -DHIL_PORT_TESTS=ON, then make build)",
            pytrace=False,
        )
    done = subprocess.run(
        private_bus.command([str(tests)]),
        env={**os.environ, "HIL_TEST_CAN_INTERFACE": private_bus.channel},
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    output = done.stdout + done.stderr
    assert done.returncode == 0, output
    assert "SKIPPED" not in output, f"a port test skipped on a real bus:\n{output}"
    passed = re.search(r"\[  PASSED  \] (\d+) tests?\.", output)
    assert passed is not None and int(passed.group(1)) >= 6, output
