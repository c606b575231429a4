"""docker-compose.yml and the Dockerfile are checked without a Docker engine (none runs here).

The compose file is written in YAML's JSON-compatible flow style (comments only above the opening
brace), so the standard library parses it exactly as a YAML parser would. When the docker CLI has
the compose plugin, `docker compose config --quiet` (no daemon needed) checks it against the
Compose specification as well.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parents[2]
COMPOSE = REPO / "docker-compose.yml"
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
