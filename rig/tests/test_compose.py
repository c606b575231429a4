"""docker-compose.yml and the Dockerfile are checked without a Docker engine (none runs here).

The compose file is written in YAML's JSON-compatible flow style (comments only above the opening
brace), so the standard library parses it exactly as a YAML parser would, and interpolated as
compose interpolates it (tools/compose_file.py). When the docker CLI has the compose plugin,
`docker compose config --quiet` (no daemon needed) checks it against the Compose specification as
well. What compose promises is checked as the processes it runs: the viewer on the loopback
unless VIEWER_BIND says otherwise, each service the rig waits for with a healthcheck that tells a
running service from a missing one (the viewer's run against the viewer's own command, the
firmware's against python-can's virtual bus), the files written as the invoking user, the
channel from CAN_CHANNEL. The Dockerfile's stages are read instruction by instruction: dev (the
full work tree), release (builds the firmware and the wheel), runtime (slim).
"""

from __future__ import annotations

import contextlib
import importlib.util
import os
import re
import shutil
import socket
import subprocess
import threading
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import can
import pytest

REPO = Path(__file__).resolve().parents[2]
_SPEC = importlib.util.spec_from_file_location("compose_file", REPO / "tools" / "compose_file.py")
assert _SPEC is not None and _SPEC.loader is not None
compose_file = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(compose_file)
COMPOSE = REPO / "docker-compose.yml"
DOCKERFILE = REPO / "Dockerfile"
FIRMWARE_COMMAND_LINE = REPO / "firmware" / "platform" / "linux" / "CommandLine.cpp"
TOP_LEVEL_KEYS = {"name", "services", "networks", "volumes", "configs", "secrets"}
SERVICE_KEYS = {
    "build",
    "image",
    "network_mode",
    "init",
    "command",
    "restart",
    "depends_on",
    "environment",
    "volumes",
    "privileged",
    "profiles",
    "user",
    "healthcheck",
}
HANG_GUARD_S = 120.0  # rerun's start on a loaded machine; not a timing check


def _compose() -> dict[str, Any]:
    """The compose file as `docker compose` reads it in a shell with nothing set."""
    compose: dict[str, Any] = compose_file.load(COMPOSE)
    compose["services"] = compose_file.services(COMPOSE, {})
    return compose


def test_compose_parses_and_uses_only_known_keys() -> None:
    compose = _compose()
    assert set(compose) <= TOP_LEVEL_KEYS | {k for k in compose if k.startswith("x-")}
    assert {"firmware", "rig", "viewer"} <= set(compose["services"])
    for name, service in compose["services"].items():
        unknown = set(service) - SERVICE_KEYS
        assert not unknown, f"service {name}: unknown keys {unknown}"
        assert "image" in service or "build" in service, name
        assert isinstance(service["command"], list) and all(isinstance(a, str) for a in service["command"])


def test_every_service_is_on_the_host_network_without_published_ports() -> None:
    for name, service in _compose()["services"].items():
        assert service["network_mode"] == "host", name
        assert "ports" not in service, f"{name}: ports are meaningless with host networking"


def test_images_are_built_from_this_repository() -> None:
    services = _compose()["services"]
    built = {s["image"]: s["build"] for s in services.values() if "build" in s}
    for name, service in services.items():
        assert service["image"] in built, f"{name}: image {service['image']} is built by no service"
    for build in built.values():
        dockerfile = REPO / build["context"] / build.get("dockerfile", "Dockerfile")
        text = dockerfile.read_text()
        assert re.search(r"^FROM debian:bookworm\b", text, re.MULTILINE), dockerfile
        assert "tools/deps" in text and "make build" in text, dockerfile
        if "target" in build:
            assert build["target"] in _stages(dockerfile), f"{dockerfile} has no stage {build['target']}"


def test_depends_on_names_existing_services_and_has_no_cycle() -> None:
    services = _compose()["services"]
    for name, service in services.items():
        for dependency in service.get("depends_on", []):
            assert dependency in services, f"{name} depends on unknown service {dependency}"
    state: dict[str, str] = {}

    def visit(name: str) -> None:
        assert state.get(name) != "open", f"depends_on cycle through {name}"
        if state.get(name) == "done":
            return
        state[name] = "open"
        for dependency in services[name].get("depends_on", []):
            visit(dependency)
        state[name] = "done"

    for name in services:
        visit(name)


def test_commands_name_what_the_repository_has() -> None:
    makefile = (REPO / "Makefile").read_text()
    targets = set(re.findall(r"^([a-z-]+):", makefile, re.MULTILINE))
    for name, service in _compose()["services"].items():
        command = service["command"]
        if command[:2] == ["sh", "-c"]:  # make, then hand ./out to the invoking user
            made = re.match(r"make ([a-z -]+);", command[2])
            assert made and set(made[1].split()) <= targets, f"{name}: {command[2]}"
        elif command[0] == "make":
            assert set(command[1:]) <= targets, f"{name}: make {command[1:]} is not a Makefile target"
        elif command[0].startswith("build/bin/"):
            assert command[0] == "build/bin/joint-firmware", f"{name}: unexpected program {command[0]}"
            command_line = FIRMWARE_COMMAND_LINE.read_text()
            options = set(re.findall(r'add_(?:option|flag)\("(--[a-z-]+)"', command_line))
            given = {arg for arg in command[1:] if arg.startswith("--")}
            assert given <= options, f"{name}: the firmware has no option {given - options}"
        elif command[0] == ".venv/bin/hilrig":
            from hilrig.cli import build_parser

            try:  # the command line hilrig itself would accept (argparse exits on a bad one)
                build_parser(command[1:]).parse_args(command[1:])
            except SystemExit as error:
                raise AssertionError(f"{name}: hilrig refuses {command[1:]}") from error
        else:
            assert command[0] == ".venv/bin/rerun", f"{name}: unexpected program {command[0]}"
        for volume in service.get("volumes", []):
            assert volume["type"] == "bind", volume
            assert volume["source"].startswith("./") and volume["target"].startswith("/src/"), volume
            # A missing ./out is refused, not made by the daemon as root.
            assert volume["bind"]["create_host_path"] is False, volume


def test_dockerignore_keeps_host_builds_out_of_the_image() -> None:
    ignored = (REPO / ".dockerignore").read_text().split()
    assert {".venv", "build", "out"} <= set(ignored)


def test_docker_compose_config_when_the_cli_has_compose() -> None:
    docker = shutil.which("docker")
    if docker is None:
        pytest.skip("no docker CLI on this machine")
    probe = subprocess.run([docker, "compose", "version"], capture_output=True, text=True, check=False)
    if probe.returncode != 0:
        pytest.skip("docker CLI without the compose plugin")
    result = subprocess.run(
        [docker, "compose", "-f", str(COMPOSE), "--profile", "test", "config", "--quiet"],
        capture_output=True,
        text=True,
        check=False,
        cwd=REPO,
    )
    assert result.returncode == 0, result.stderr


# --- What compose promises, as the processes it runs ------------------------------------------
def test_the_viewer_listens_on_the_loopback_unless_asked_otherwise() -> None:
    def bind(environ: dict[str, str]) -> str:
        command = compose_file.services(COMPOSE, environ)["viewer"]["command"]
        return str(command[command.index("--bind") + 1])

    assert bind({}) == "127.0.0.1"
    assert bind({"VIEWER_BIND": "0.0.0.0"}) == "0.0.0.0"


def test_every_service_the_rig_waits_for_is_healthy_first() -> None:
    services = _compose()["services"]
    for name, service in services.items():
        depends_on = service.get("depends_on", {})
        assert isinstance(depends_on, dict), f"{name}: depends_on with conditions, not a start order"
        for dependency, condition in depends_on.items():
            assert condition == {"condition": "service_healthy"}, f"{name} -> {dependency}: {condition}"
            check = services[dependency].get("healthcheck")
            assert check is not None and check["test"][0] == "CMD", f"{dependency} has no healthcheck"
    assert set(services["rig"]["depends_on"]) == {"firmware", "viewer"}


def test_what_the_services_write_is_the_invoking_users() -> None:
    services = compose_file.services(COMPOSE, {"UID": "1234", "GID": "5678"})
    for name, service in services.items():
        if service.get("privileged"):  # root for namespaces and vcan: it hands ./out back
            assert "chown -R 1234:5678 /src/out" in service["command"][-1], name
        else:
            assert service["user"] == "1234:5678", name
    assert compose_file.services(COMPOSE, {})["rig"]["user"] == "1000:1000"  # nothing exported


def test_the_channel_is_can_channel(monkeypatch: pytest.MonkeyPatch) -> None:
    services = compose_file.services(COMPOSE, {"CAN_CHANNEL": "can7"})
    text = repr(services)
    assert "vcan0" not in text, "a hard-coded channel"
    firmware = services["firmware"]["command"]
    assert firmware[firmware.index("--can") + 1] == "can7"
    rig = services["rig"]
    from hilrig.cli import build_parser
    from hilrig.cli.common import bus_config

    for key, value in rig["environment"].items():  # the rig's bus, as hilrig resolves it there
        monkeypatch.setenv(key, value)
    monkeypatch.setenv("CAN_CONFIG", "{}")
    args = build_parser(rig["command"][1:]).parse_args(rig["command"][1:])
    assert bus_config(args)["channel"] == "can7"
    assert "vcan0" in repr(compose_file.services(COMPOSE, {})["firmware"]["command"])  # the default


def _free_ports(count: int) -> list[int]:
    """`count` distinct free ports: every probe stays bound until all are picked (the kernel
    may hand a port it just got back to the next probe)."""
    with contextlib.ExitStack() as probes:
        ports = []
        for _ in range(count):
            probe = probes.enter_context(socket.socket())
            probe.bind(("127.0.0.1", 0))
            ports.append(int(probe.getsockname()[1]))
        return ports


def _in_checkout(command: list[str]) -> list[str]:
    """A healthcheck's or service's command as it runs here: the image's /src is this checkout."""
    program = command[1] if command[0] == "CMD" else command[0]
    rest = command[2:] if command[0] == "CMD" else command[1:]
    return [str(REPO / program) if "/" in program else program, *rest]


def _listening_addresses(port: int) -> set[str]:
    """The local addresses a TCP socket listens on at `port` (/proc/net/tcp, IPv4)."""
    found = set()
    for line in Path("/proc/net/tcp").read_text().splitlines()[1:]:
        local, state = line.split()[1], line.split()[3]
        address, _, hex_port = local.partition(":")
        if state == "0A" and int(hex_port, 16) == port:  # LISTEN
            found.add(socket.inet_ntoa(bytes.fromhex(address)[::-1]))
    return found


def test_the_viewers_healthcheck_tells_a_running_viewer_from_none(tmp_path: Path) -> None:
    grpc_port, web_port = _free_ports(2)
    environ = {"VIEWER_GRPC_PORT": str(grpc_port), "VIEWER_PORT": str(web_port)}
    viewer = compose_file.services(COMPOSE, environ)["viewer"]
    check = _in_checkout(viewer["healthcheck"]["test"])

    def healthy() -> bool:
        return subprocess.run(check, capture_output=True, check=False, timeout=30).returncode == 0

    assert not healthy(), "healthy before the viewer runs"
    log = (tmp_path / "viewer.log").open("wb")
    process = subprocess.Popen(
        _in_checkout(viewer["command"]),
        cwd=tmp_path,
        env={**os.environ, **viewer["environment"]},
        stdout=log,
        stderr=subprocess.STDOUT,
        process_group=0,
    )
    try:
        deadline = time.monotonic() + HANG_GUARD_S
        while not healthy():
            assert process.poll() is None, (tmp_path / "viewer.log").read_text()
            assert time.monotonic() < deadline, "the viewer never became healthy"
            with contextlib.suppress(subprocess.TimeoutExpired):
                process.wait(timeout=0.2)  # a pause that ends at once if the viewer dies
        assert _listening_addresses(int(environ["VIEWER_GRPC_PORT"])) == {"127.0.0.1"}
    finally:
        os.killpg(process.pid, 15)
        process.wait(timeout=30)
        log.close()
    assert not healthy(), "healthy after the viewer stopped"


def test_the_firmwares_healthcheck_is_healthy_while_a_heartbeat_is_heard(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Run on python-can's virtual bus in this process (the image has a real channel): exit 0
    with the node's heartbeat going, 1 on a silent bus. In the image hilrig is the wheel, whose
    generators are hilrig.boardproto; here they are the checkout's boardproto."""
    from boardproto.cia301 import heartbeat_cob_id
    from hilrig.table import BOARD_TABLE

    boot_up = can.Message(
        arbitration_id=heartbeat_cob_id(BOARD_TABLE.node.default_node_id), data=bytes(1), is_extended_id=False
    )

    firmware = compose_file.services(COMPOSE, {})["firmware"]
    command = firmware["healthcheck"]["test"]
    assert command[1:3] == [".venv/bin/python", "-c"]
    code = command[3].replace("hilrig.boardproto.", "boardproto.")
    monkeypatch.setenv("CAN_INTERFACE", "virtual")

    def exit_code(channel: str) -> int:
        monkeypatch.setenv("CAN_CHANNEL", channel)
        with pytest.raises(SystemExit) as ended:
            exec(compile(code, "healthcheck", "exec"), {"__name__": "__main__"})
        return int(ended.value.code)

    stop = threading.Event()

    def heartbeat() -> None:
        with can.Bus(interface="virtual", channel="compose-heartbeat") as bus:
            while not stop.wait(0.05):
                bus.send(boot_up)

    sender = threading.Thread(target=heartbeat)
    sender.start()
    try:
        assert exit_code("compose-heartbeat") == 0
    finally:
        stop.set()
        sender.join()
    assert exit_code("compose-silent") == 1


# --- The Dockerfile's stages ---------------------------------------------------------------------
@dataclass
class Stage:
    base: str
    instructions: list[str] = field(default_factory=list)
    """Each instruction on one line (continuations joined), comments left out."""

    def runs(self) -> str:
        return "\n".join(i for i in self.instructions if i.startswith("RUN "))

    def apt_packages(self) -> set[str]:
        packages: set[str] = set()
        for install in re.findall(r"apt-get install ([^&;]*)", self.runs()):
            packages |= {word for word in install.split() if not word.startswith("-")}
        return packages


def _stages(dockerfile: Path = DOCKERFILE) -> dict[str, Stage]:
    """The stages by name, in order (a stage without AS is named by its position)."""
    text = re.sub(r"\\\n\s*", " ", dockerfile.read_text())
    stages: dict[str, Stage] = {}
    for line in text.splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        start = re.fullmatch(r"FROM\s+(\S+)(?:\s+AS\s+(\S+))?", line, re.IGNORECASE)
        if start:
            stages[start[2] or str(len(stages))] = Stage(start[1])
        else:
            list(stages.values())[-1].instructions.append(line)
    return stages


def test_dockerfile_builds_a_dev_image_and_a_slim_runtime_the_default() -> None:
    stages = _stages()
    assert {"dev", "runtime"} <= set(stages)
    assert list(stages)[-1] == "runtime", "a plain `docker build .` builds the last stage"
    assert stages["dev"].base == "debian:bookworm"
    assert "tools/deps" in stages["dev"].runs() and "make build" in stages["dev"].runs()
    assert stages["runtime"].base == "debian:bookworm-slim"


def test_runtime_installs_no_compilers_emulator_or_browser_and_not_the_sources() -> None:
    runtime = _stages()["runtime"]
    tooling = re.compile(
        r"(g\+\+|gcc|cpp|clang.*|cmake|ninja-build|make|.*-dev|qemu.*|chromium.*|valgrind|linux-image.*)"
    )
    assert not {p for p in runtime.apt_packages() if tooling.fullmatch(p)}, runtime.apt_packages()
    assert "python3" in runtime.apt_packages()
    assert "tools/deps" not in runtime.runs() and not re.search(r"\bmake\b", runtime.runs())
    copies = [i for i in runtime.instructions if i.startswith("COPY ")]
    assert all("--from=" in copy or copy.split()[1] == "requirements.lock" for copy in copies), copies


def test_runtime_gets_a_release_firmware_and_hilrig_from_its_wheels() -> None:
    stages = _stages()
    runtime = stages["runtime"]
    firmware = [i for i in runtime.instructions if i.endswith(" /src/build/bin/joint-firmware")]
    assert len(firmware) == 1, "the firmware goes where hilrig looks for it from WORKDIR /src"
    copy = re.fullmatch(r"COPY --from=(\S+) (\S+) \S+", firmware[0])
    assert copy, firmware[0]
    source_stage, built = copy.groups()
    builder = stages[source_stage].runs()
    configure = next(line for line in builder.splitlines() if "cmake -S" in line)
    for flag in ("-DCMAKE_BUILD_TYPE=Release", "-DHIL_SANITIZE=OFF", "-DHIL_TESTS=OFF"):
        assert flag in configure, f"the runtime's firmware is built without {flag}"
    build_dir = re.search(r"-B (\S+)", configure)
    assert build_dir, configure
    assert built == f"/src/{build_dir[1]}/bin/joint-firmware"
    assert "tools/dist.py --out /dist" in builder, "the wheels as `make dist` builds them"
    assert f"--from={source_stage} /dist/" in "\n".join(runtime.instructions)
    assert "python3 -m venv /src/.venv" in runtime.runs()
    assert "--constraint /tmp/requirements.lock" in runtime.runs(), "dependencies at the pinned versions"
    assert "WORKDIR /src" in runtime.instructions
    dependencies = tomllib.loads((REPO / "rig" / "pyproject.toml").read_text())["project"]["dependencies"]
    assert any(d.startswith("rerun-sdk") for d in dependencies), "the `rerun` CLI the viewer service runs"
