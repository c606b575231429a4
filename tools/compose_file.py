"""docker-compose.yml as the tests read it without a Docker engine: parsed (JSON-compatible YAML,
comments only above the opening brace) and interpolated as compose interpolates it.

    services(path, environ) -> {name: service}, every string with ${NAME}, ${NAME:-default},
    ${NAME-default} and $$ resolved from `environ` as `docker compose` resolves them from the shell.
"""

from __future__ import annotations

import json
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

_VARIABLE = re.compile(r"\$(?:\$|\{(?P<name>[A-Za-z_][A-Za-z0-9_]*)(?:(?P<op>:?-)(?P<default>[^}]*))?\})")


def load(path: Path) -> dict[str, Any]:
    """The compose file as written (no interpolation)."""
    lines = path.read_text().splitlines()
    first = next(i for i, line in enumerate(lines) if not line.lstrip().startswith("#"))
    if any(line.lstrip().startswith("#") for line in lines[first:]):
        raise ValueError(f"{path}: comments only above the opening brace (JSON has none)")
    loaded: dict[str, Any] = json.loads("\n".join(lines[first:]))
    return loaded


def interpolate(value: Any, environ: Mapping[str, str]) -> Any:
    """`value` with every string interpolated; lists and mappings walked."""
    if isinstance(value, str):
        return _VARIABLE.sub(lambda match: _resolve(match, environ), value)
    if isinstance(value, list):
        return [interpolate(item, environ) for item in value]
    if isinstance(value, dict):
        return {key: interpolate(item, environ) for key, item in value.items()}
    return value


def _resolve(match: re.Match[str], environ: Mapping[str, str]) -> str:
    if match.group(0) == "$$":
        return "$"
    name, op, default = match["name"], match["op"], match["default"] or ""
    value = environ.get(name)
    if op == ":-" and not value:
        return default
    if op == "-" and value is None:
        return default
    return value or ""


def services(path: Path, environ: Mapping[str, str]) -> dict[str, dict[str, Any]]:
    """The services, interpolated from `environ`."""
    resolved: dict[str, dict[str, Any]] = interpolate(load(path)["services"], environ)
    return resolved
