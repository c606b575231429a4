"""docker-compose.yml runs what it says. No Docker engine runs here, so each service's command, as
written in the file, is started as a plain process on one private vcan bus (the services use the
host's network and its vcan0; a private bus is a network namespace with its own vcan0 and
loopback): the firmware free-running, the viewer's Rerun server, then the rig's demo in real time
against that firmware, streaming live to the viewer as the file's HIL_TRACE says. Afterwards the
viewer holds the rig's fields: `rerun download` of the viewer's stream is read back.

Paths in the commands are relative to the image's /src, which is this repository; the processes
run in this test's output folder so the rig's out/ lands there. The file is interpolated as
compose does in a shell with nothing set (tools/compose_file.py), and the rig starts, as its
depends_on says, once the firmware's and the viewer's healthchecks pass: run in the namespace
against those processes.
"""

from __future__ import annotations

import contextlib
import importlib.util
import os
import signal
import socket
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from conftest import REPO, TABLE

from hilrig import resources
from hilrig.observe.paths import entity_paths
from hilrig.session.netns import PrivateBus

pytestmark = [pytest.mark.bus, pytest.mark.realtime]  # wall-clock time: runs alone

COMPOSE = REPO / "docker-compose.yml"
_SPEC = importlib.util.spec_from_file_location("compose_file", REPO / "tools" / "compose_file.py")
assert _SPEC is not None and _SPEC.loader is not None
compose_file = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(compose_file)
HANG_GUARD_S = 600.0  # the software-emulated VM starts rerun and Python slowly; not a timing check
VIEWER_GRPC_PORT = 9876  # the port of the viewer's command and of the rig's HIL_TRACE
FIRMWARE_IN_IMAGE = "build/bin/joint-firmware"


def compose_services() -> dict[str, dict[str, Any]]:
    """The services of the compose file, interpolated with nothing set (the defaults)."""
    services: dict[str, dict[str, Any]] = compose_file.services(COMPOSE, {})
    return services


def as_processes(command: list[str]) -> list[str]:
    """A service's command (or healthcheck, CMD ...) with the image's /src-relative programs made
    absolute; in the image hilrig is the wheel, whose generators are hilrig.boardproto."""
    command = command[1:] if command[0] == "CMD" else command
    program = command[0]
    rest = [arg.replace("hilrig.boardproto.", "boardproto.") for arg in command[1:]]
    if program == FIRMWARE_IN_IMAGE:
        # The checkout's firmware as every scenario takes it: $HIL_FIRMWARE when set, else the
        # release build under user-mode Linux, where the image's ASan build cannot start
        # (hilrig.resources).
        return [str(resources.DEFAULT_FIRMWARE), *rest]
    return [str(REPO / program) if "/" in program else program, *rest]


class Services:
    """The compose services started as processes in one namespace, stopped in reverse order."""

    def __init__(self, bus: PrivateBus, folder: Path) -> None:
        self.bus = bus
        self.folder = folder
        self.started: list[tuple[str, subprocess.Popen[bytes]]] = []

    def start(
        self, name: str, service: dict[str, Any], argv: list[str] | None = None
    ) -> subprocess.Popen[bytes]:
        environment = {**os.environ, **service.get("environment", {})}
        log = (self.folder / f"{name}.log").open("wb")
        process = self.bus.popen(
            argv or as_processes(service["command"]),
            cwd=self.folder,
            env=environment,
            stdout=log,
            stderr=subprocess.STDOUT,
            process_group=0,  # rerun's launcher does not pass signals on: stop the whole group
        )
        log.close()
        self.started.append((name, process))
        return process

    def stop(self) -> None:
        for _, process in reversed(self.started):
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGTERM)
        for _, process in reversed(self.started):
            try:
                process.wait(timeout=30)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait()

    def log(self, name: str) -> str:
        return (self.folder / f"{name}.log").read_text(errors="replace")


@pytest.fixture
def services(private_bus: PrivateBus, scenario_dir: Path) -> Iterator[Services]:
    running = Services(private_bus, scenario_dir)
    try:
        yield running
    finally:
        running.stop()


def wait_until_healthy(
    bus: PrivateBus, service: dict[str, Any], process: subprocess.Popen[bytes], what: str
) -> None:
    """Run the service's healthcheck in the namespace until it passes (compose's depends_on:
    condition service_healthy), while the service runs."""
    deadline = time.monotonic() + HANG_GUARD_S
    check = bus.command(as_processes(service["healthcheck"]["test"]))
    environment = {**os.environ, **service.get("environment", {})}
    while subprocess.run(check, env=environment, capture_output=True, check=False).returncode != 0:
        assert process.poll() is None, f"{what} exited with {process.returncode} before it was healthy"
        assert time.monotonic() < deadline, f"{what} never passed its healthcheck"
        with contextlib.suppress(subprocess.TimeoutExpired):
            process.wait(timeout=0.5)  # a pause that ends at once if the process dies


def wait_for_port(bus: PrivateBus, port: int, process: subprocess.Popen[bytes], what: str) -> None:
    deadline = time.monotonic() + HANG_GUARD_S
    while True:
        with bus.entered():
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                return
            except OSError:
                pass
        assert process.poll() is None, f"{what} exited with {process.returncode} before listening on {port}"
        assert time.monotonic() < deadline, f"{what} did not listen on port {port}"
        with contextlib.suppress(subprocess.TimeoutExpired):
            process.wait(timeout=0.5)  # a pause that ends at once if the process dies


@pytest.mark.filterwarnings("ignore:RRD file has no footer")  # a stream, downloaded as it goes
def test_the_compose_services_run_what_they_say(services: Services, scenario_dir: Path) -> None:
    from hilrig.observe.reader import Trace  # imports rerun: slow in the VM

    compose = compose_services()
    firmware = services.start("firmware", compose["firmware"])
    viewer = services.start("viewer", compose["viewer"])
    wait_for_port(services.bus, VIEWER_GRPC_PORT, viewer, "the viewer")
    wait_until_healthy(services.bus, compose["viewer"], viewer, "the viewer")
    wait_until_healthy(services.bus, compose["firmware"], firmware, "the firmware")
    assert f"127.0.0.1:{VIEWER_GRPC_PORT}" in compose["rig"]["environment"]["HIL_TRACE"]

    rig = services.start("rig", compose["rig"])
    assert rig.wait(timeout=HANG_GUARD_S) == 0, services.log("rig")
    assert firmware.poll() is None, f"the firmware died: {services.log('firmware')}"
    summary = (scenario_dir / "out" / "rig" / "summary.txt").read_text()
    assert "velocity tracking error" in summary, summary

    # What the viewer got: its stream, downloaded as a person's second viewer would see it.
    downloaded = scenario_dir / "download"
    downloaded.mkdir(exist_ok=True)
    url = f"rerun+http://127.0.0.1:{VIEWER_GRPC_PORT}/proxy"
    download = services.start(
        "download", {}, [str(REPO / ".venv/bin/rerun"), "download", url, "-o", str(downloaded)]
    )
    paths = entity_paths(TABLE)
    wanted = [paths[name] for name in ("motor_velocity", "velocity_setpoint", "fault_flags")]
    # The rig has exited: its own trace file holds every cycle it ran. How many that is depends
    # on the host's speed (real time); that the viewer got all of them does not.
    rig_trace = Trace.read(scenario_dir / "out" / "rig" / "trace.rrd")
    rig_cycles = len(rig_trace.scalars[paths["motor_velocity"]])
    assert rig_cycles > 0, "the rig's own trace holds no cycle"
    deadline = time.monotonic() + HANG_GUARD_S
    trace: Trace | None = None
    while True:  # the download streams on (the viewer's stream never ends): read what came so far
        for path in downloaded.glob("*.rrd"):
            try:
                trace = Trace.read(path)
            except Exception:  # the file is being written: try again
                trace = None
            if (
                trace is not None
                and all(trace.scalars.get(p) for p in wanted)
                and len(trace.scalars[paths["motor_velocity"]]) >= rig_cycles
            ):
                break
        else:
            assert download.poll() is None, f"rerun download ended: {services.log('download')}"
            assert time.monotonic() < deadline, f"the viewer never held {wanted} for {rig_cycles} cycles"
            with contextlib.suppress(subprocess.TimeoutExpired):
                download.wait(timeout=1.0)
            continue
        break
    assert trace is not None
    demo_cycles = len(trace.scalars[paths["motor_velocity"]])
    assert demo_cycles == rig_cycles, f"{demo_cycles} of the rig's {rig_cycles} cycles reached the viewer"
    assert max(trace.scalars[paths["velocity_setpoint"]]) == pytest.approx(3.0), "the demo's velocity profile"
