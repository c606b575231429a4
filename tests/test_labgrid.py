"""A scenario through labgrid end to end, as on a board farm: labgrid's own coordinator and
exporter (loopback, in this test's namespace), a place whose CAN port the exporter publishes
(`hilrig.lab.NetworkCANPort`), acquired with `labgrid-client`, and an env YAML that imports
hilrig's labgrid plugin and gives the target its `CANDriver`, an ExternalPowerDriver that powers
the "board" (the firmware, free-running, started and stopped by `lab_board_power.py`) and an
ExternalConsoleDriver on the board's output. pytest then runs one real-time scenario of the
two-worlds file unchanged with `--lg-env` (docs/labgrid.md): the plugin powers the board on and
waits for its boot-up, the rig talks to it on the target's bus, the console lands beside the
scenario's evidence and the board is powered off at the end.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from conftest import NODE_ID, REALTIME_FIRMWARE_PERIOD_US, REPO

from hilrig.session.firmware import DEFAULT_EXECUTABLE, parse_stop_line
from hilrig.session.netns import PrivateBus

pytestmark = [pytest.mark.bus, pytest.mark.slow, pytest.mark.realtime]

COORDINATOR = "127.0.0.1:20408"
"""labgrid's default port, on this test's own loopback (its namespace)."""
PLACE = "joint-1"
SCENARIO = "test_observe_and_command_realtime_without_physics"
POWER = Path(__file__).with_name("lab_board_power.py")
BIN = Path(sys.executable).parent
INNER_RUN_TIMEOUT_S = 540.0
"""Hang guard for the inner pytest (below pytest.ini's 600 s, so its output is not lost)."""
CLIENT_TIMEOUT_S = 120.0
"""Hang guard for one labgrid-client command in the emulated VM, not a timing check."""
EXPORTED_TRIES = 60
"""labgrid-client calls (each a process start) before the exporter's resource must be listed."""


def _exporter_config(private_bus: PrivateBus) -> str:
    return f"""board-bus:
  NetworkCANPort:
    host: localhost
    ifname: {private_bus.channel}
    bitrate: 500000
"""


def _env_config(state: Path) -> str:
    on = f"{sys.executable} {POWER} on {state} {DEFAULT_EXECUTABLE} {NODE_ID} {REALTIME_FIRMWARE_PERIOD_US}"
    return f"""imports:
  - hilrig.lab
options:
  coordinator_address: "{COORDINATOR}"
targets:
  main:
    resources:
      RemotePlace:
        name: {PLACE}
    drivers:
      CANDriver: {{}}
      ExternalPowerDriver:
        cmd_on: "{on}"
        cmd_off: "{sys.executable} {POWER} off {state}"
      ExternalConsoleDriver:
        cmd: "tail -n +1 -F {state / "board.log"}"
"""


def _client(private_bus: PrivateBus, *argv: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        private_bus.command([str(BIN / "labgrid-client"), "-x", COORDINATOR, *argv]),
        capture_output=True,
        text=True,
        timeout=CLIENT_TIMEOUT_S,
    )


def _start(private_bus: PrivateBus, argv: list[str], log: Path) -> subprocess.Popen[bytes]:
    """A daemon of labgrid's, in the log's folder (the coordinator keeps its places there)."""
    with log.open("wb") as out:
        return private_bus.popen(
            argv, cwd=log.parent, stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT
        )


def _stop(process: subprocess.Popen[bytes]) -> None:
    process.terminate()
    try:
        process.wait(timeout=30)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()


@pytest.fixture
def lab(private_bus: PrivateBus, scenario_dir: Path) -> Iterator[Path]:
    """A coordinator and an exporter of the bus, the place made and acquired; yields the folder
    of their logs. The coordinator starts with no places (a run before this one left its own)."""
    for stale in ("places.yaml", "resources.yaml"):
        (scenario_dir / stale).unlink(missing_ok=True)
    coordinator = _start(
        private_bus, [str(BIN / "labgrid-coordinator"), "-l", COORDINATOR], scenario_dir / "coordinator.log"
    )
    exporter = None
    try:
        # The exporter gives up at once on a coordinator that does not answer yet: start it only
        # once a client's call gets through (a busy host may take a while to bring it up).
        for _ in range(EXPORTED_TRIES):
            if _client(private_bus, "places").returncode == 0:
                break
            assert coordinator.poll() is None, (scenario_dir / "coordinator.log").read_text()
        else:
            pytest.fail(
                f"labgrid's coordinator never answered: {(scenario_dir / 'coordinator.log').read_text()}"
            )
        exported = scenario_dir / "exporter.yaml"
        exported.write_text(_exporter_config(private_bus))
        exporter = _start(
            private_bus,
            [str(BIN / "labgrid-exporter"), "-c", COORDINATOR, "-n", "rig", str(exported)],
            scenario_dir / "exporter.log",
        )
        for _ in range(EXPORTED_TRIES):
            listed = _client(private_bus, "resources")
            if "rig/board-bus/NetworkCANPort" in listed.stdout:
                break
            assert coordinator.poll() is None, (scenario_dir / "coordinator.log").read_text()
            assert exporter.poll() is None, (scenario_dir / "exporter.log").read_text()
        else:
            pytest.fail(f"the exporter's CAN port never reached the coordinator: {listed.stderr}")
        for argv in (("create",), ("add-match", "rig/board-bus/*"), ("acquire",)):
            done = _client(private_bus, "-p", PLACE, *argv)
            assert done.returncode == 0, f"labgrid-client {' '.join(argv)}: {done.stderr}"
        yield scenario_dir
        released = _client(private_bus, "-p", PLACE, "release")
        assert released.returncode == 0, released.stderr
    finally:
        for process in (exporter, coordinator):
            if process is not None:
                _stop(process)


def test_a_scenario_runs_on_a_labgrid_place_with_its_power_and_console(
    private_bus: PrivateBus, lab: Path
) -> None:
    state = lab / "board"
    env_file = lab / "env.yaml"
    env_file.write_text(_env_config(state))
    inner_out = lab / "out"
    command = [
        sys.executable, "-m", "pytest", "tests/test_two_worlds.py",
        "-p", "labgrid.pytestplugin", "--lg-env", str(env_file),
    ]  # fmt: skip
    inner = subprocess.run(
        private_bus.command([*command, "-k", SCENARIO, "-p", "no:cacheprovider", "-q", "-rs"]),
        cwd=REPO,
        env={**os.environ, "HIL_OUT_DIR": str(inner_out)},
        capture_output=True,
        text=True,
        timeout=INNER_RUN_TIMEOUT_S,
    )
    output = inner.stdout + inner.stderr
    assert inner.returncode == 0, f"the scenario through labgrid failed (exit {inner.returncode}):\n{output}"
    assert re.search(r"\b1 passed\b", output), output
    evidence = inner_out / "scenarios" / SCENARIO
    assert (evidence / "bus.log").stat().st_size > 0, f"no bus log in {evidence}"
    assert not (evidence / "firmware.log").exists(), f"the rig started a firmware in {evidence}"
    assert not (state / "board.pid").exists(), "the board was not powered off after the session"
    parsed = parse_stop_line((state / "board.log").read_text(errors="replace"))
    assert parsed is not None, f"the board did not stop on power off: {state / 'board.log'}"
    counters = parsed[1]
    assert counters["frames received"] > 0 and counters["cycles"] > 0, counters
    console = (evidence / "console.log").read_text(errors="replace")
    assert f"node {NODE_ID}, " in console and "free-running mode" in console, f"console: {console!r}"
    print(f"\n{output.strip().splitlines()[-1]}; the board: {counters}")
