"""docker-compose.yml and the Dockerfile are checked without a Docker engine (none runs here).

The compose file is written in YAML's JSON-compatible flow style (comments only above the opening
brace), so the standard library parses it exactly as a YAML parser would. When the docker CLI has
the compose plugin, `docker compose config --quiet` (no daemon needed) checks it against the
Compose specification as well. The Dockerfile's stages are read instruction by instruction: dev
(the full work tree), release (builds the firmware and the wheels), runtime (slim).
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parents[2]
COMPOSE = REPO / "docker-compose.yml"
DOCKERFILE = REPO / "Dockerfile"
FIRMWARE_MAIN = REPO / "firmware" / "platform" / "linux" / "main.cpp"
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
}


def _compose() -> dict[str, Any]:
    lines = COMPOSE.read_text().splitlines()
    body = [line for line in lines if not line.lstrip().startswith("#")]
    first = next(i for i, line in enumerate(lines) if not line.lstrip().startswith("#"))
    assert all(not line.lstrip().startswith("#") for line in lines[first:]), (
        "comments only above the opening brace: JSON has none"
    )
    return json.loads("\n".join(body))


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
        if command[0] == "make":
            assert set(command[1:]) <= targets, f"{name}: make {command[1:]} is not a Makefile target"
        elif command[0].startswith("build/bin/"):
            assert command[0] == "build/bin/joint-firmware", f"{name}: unexpected program {command[0]}"
            options = set(re.findall(r'add_(?:option|flag)\("(--[a-z-]+)"', FIRMWARE_MAIN.read_text()))
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
            host, _, container = volume.partition(":")
            assert host.startswith("./") and container.startswith("/src/"), volume


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
