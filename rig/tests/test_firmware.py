"""The firmware process helper, with small Python programs standing in for the firmware."""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from hilrig.errors import FirmwareError
from hilrig.session.firmware import Firmware, describe_exit

CRASH = """
import sys
for n in range(30):
    print(f"log line {n}", file=sys.stderr)
sys.exit(3)
"""
IGNORES_SIGTERM = """
import signal, sys, threading
signal.signal(signal.SIGTERM, signal.SIG_IGN)
print("ready", flush=True)
threading.Event().wait()
"""
WAITS = "import threading; threading.Event().wait()"


class ScriptLauncher:
    """Runs a Python script instead of the firmware; records the argv it was given."""

    channel = "vcan0"

    def __init__(self, script: str, *, stdout_pipe: bool = False) -> None:
        self.script = script
        self.stdout_pipe = stdout_pipe
        self.argv: list[str] = []

    def popen(self, argv: list[str], **kwargs: Any) -> subprocess.Popen[Any]:
        self.argv = list(argv)
        if self.stdout_pipe:
            kwargs["stdout"] = subprocess.PIPE
        return subprocess.Popen([sys.executable, "-c", self.script], **kwargs)


def _firmware(launcher: ScriptLauncher, tmp_path: Path, **kwargs: Any) -> Firmware:
    return Firmware(
        launcher,
        node_id=0x10,
        period_us=500,
        log_path=tmp_path / "fw.log",
        executable=Path(sys.executable),
        **kwargs,
    )


def test_command_line_is_the_firmwares(tmp_path: Path) -> None:
    launcher = ScriptLauncher(WAITS)
    firmware = Firmware(
        launcher,
        node_id=0x11,
        period_us=500,
        log_path=tmp_path / "fw.log",
        executable=Path(sys.executable),
        params_file=tmp_path / "p.toml",
    )
    with firmware:
        assert firmware.running
    assert launcher.argv == [
        sys.executable,
        "--can",
        "vcan0",
        "--node-id",
        "17",
        "--mode",
        "lockstep",
        "--period-us",
        "500",
        "--params",
        str(tmp_path / "p.toml"),
    ]


def test_crash_raises_firmware_error_with_the_last_log_lines(tmp_path: Path) -> None:
    firmware = _firmware(ScriptLauncher(CRASH), tmp_path)
    firmware.start()
    assert firmware.process is not None
    firmware.process.wait(timeout=10)
    with pytest.raises(FirmwareError) as info:
        firmware.check()
    message = str(info.value)
    assert "exited with code 3" in message
    assert message.endswith("log line 29")
    assert "log line 10\n" in message and "log line 9\n" not in message  # the last 20 only
    firmware.stop()


def test_stop_sends_sigterm(tmp_path: Path) -> None:
    firmware = _firmware(ScriptLauncher(WAITS), tmp_path)
    firmware.start()
    assert firmware.stop() == -signal.SIGTERM


def test_stop_kills_a_process_that_ignores_sigterm(tmp_path: Path) -> None:
    firmware = _firmware(ScriptLauncher(IGNORES_SIGTERM, stdout_pipe=True), tmp_path, term_timeout_s=0.2)
    firmware.start()
    assert firmware.process is not None and firmware.process.stdout is not None
    assert firmware.process.stdout.readline() == b"ready\n"  # its SIGTERM handler is in place
    assert firmware.stop() == -signal.SIGKILL
    firmware.process.stdout.close()


def test_missing_executable_says_to_build(tmp_path: Path) -> None:
    firmware = Firmware(
        ScriptLauncher(WAITS), node_id=1, log_path=tmp_path / "fw.log", executable=tmp_path / "joint-firmware"
    )
    with pytest.raises(FirmwareError, match="does not exist: build the firmware"):
        firmware.start()


def test_exit_descriptions() -> None:
    assert describe_exit(0) == "exited with code 0"
    assert describe_exit(-signal.SIGSEGV) == "was killed by SIGSEGV"
