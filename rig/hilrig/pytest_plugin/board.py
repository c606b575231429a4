"""What board a project's scenarios run: its table, its EDS, its firmware and its plant, from the
project's pytest configuration (ini options, paths relative to the ini file), or from a
`hil_board` fixture the project overrides.

    [pytest]
    hil_table = board.toml                      # the board's table (board.toml format)
    hil_eds = build/board.eds                   # optional: default, generated from the table
    hil_firmware = build/toy-firmware           # the firmware executable
    hil_firmware_args = --verbose               # optional: more of its command line
    hil_plant = toy_plant:make_plant            # the plant factory, `module:callable`
                                                # or an FMU: hil_plant = model.fmu
    hil_plant_map = model.map.toml              # an FMU's plant map (hilrig.plants.fmu_map)

The firmware is started as `FIRMWARE --can CHANNEL --node-id N --mode lockstep|free --period-us P
[ARGS...]` (`hilrig.session.firmware.firmware_argv`); the plant factory is called with
(params, seed) from `make_scenario(params=..., seed=...)` and returns a
`hilrig.plants.interface.Plant`. Nothing set: hilrig's own demo board (its table, EDS and
firmware where `hilrig.resources` finds them, the joint's plant). $HIL_FIRMWARE, when set, is
the firmware whatever the ini says (a mutant); `hilrig bus` never sets it. The run's header names
the firmware and where it comes from (`report_header`).
"""

from __future__ import annotations

import importlib
import os
import shlex
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from boardproto import TableError
from hilrig import resources
from hilrig.errors import PlantMapError
from hilrig.observe.paths import GENERATED_DASHBOARD
from hilrig.plants import default_plant
from hilrig.session.builder import PlantFactory
from hilrig.table import RigTable

INI_OPTIONS: tuple[tuple[str, str], ...] = (
    (resources.TABLE_INI_OPTION, "the board's table (board.toml format); default: hilrig's demo board"),
    ("hil_eds", "the board's EDS; default: generated from hil_table (or the demo board's)"),
    ("hil_firmware", "the board's firmware executable; default: hilrig's demo firmware"),
    ("hil_firmware_args", "more arguments for the firmware's command line (shell words)"),
    (
        "hil_plant",
        "the plant factory, module:callable (params, seed) -> Plant, or an FMU (.fmu); default: the joint",
    ),
    ("hil_plant_map", "an FMU plant's map (TOML: its variables tied to the table's HIL I/O)"),
    ("hil_durations", "a JSON file of each scenario's duration [s]: the longest run first"),
)
"""The ini options of the plugin (`pytest_addoption` registers them)."""


@dataclass(frozen=True)
class HilBoard:
    """One board as the scenarios see it. node_id: the firmware's (its table's default)."""

    table: RigTable
    eds: Path
    firmware: Path
    plant: PlantFactory
    firmware_args: tuple[str, ...] = ()
    dashboard: str | None = None
    """The dashboard a scenario's trace opens with (`dashboards.BLUEPRINTS`, for this table): the
    demo joint's "overview"; the one generated from the table and plant for another board; None,
    the viewer's default."""

    @property
    def node_id(self) -> int:
        return self.table.board.node.default_node_id


def load_factory(spelled: str) -> PlantFactory:
    """The callable `module:name` names (a dotted name after the colon for an attribute of an
    attribute); a UsageError that says what is wrong otherwise."""
    module_name, colon, attribute = spelled.partition(":")
    if not colon or not module_name or not attribute:
        raise pytest.UsageError(f"hil_plant: expected module:callable, got {spelled!r}")
    try:
        found: Any = importlib.import_module(module_name)
    except ImportError as error:
        raise pytest.UsageError(f"hil_plant {spelled}: cannot import {module_name}: {error}") from None
    for part in attribute.split("."):
        if not hasattr(found, part):
            raise pytest.UsageError(f"hil_plant {spelled}: {module_name} has no {attribute}")
        found = getattr(found, part)
    if not callable(found):
        raise pytest.UsageError(f"hil_plant {spelled}: not callable")
    return found  # type: ignore[no-any-return]


def fmu_plant_factory(fmu: Path | None, plant_map: Path | None, table: RigTable) -> PlantFactory:
    """The factory of an FMU plant (`hil_plant = model.fmu`, `hil_plant_map = map.toml`; the
    map may name its FMU), its map checked now; a UsageError saying what is wrong otherwise."""
    if plant_map is None:
        raise pytest.UsageError(f"hil_plant {fmu}: an FMU needs hil_plant_map = its map (TOML)")
    try:
        from hilrig.plants.fmu import fmu_factory

        return fmu_factory(plant_map, table.board, fmu)  # type: ignore[no-any-return]
    except ImportError as error:
        raise pytest.UsageError(f"hil_plant {fmu}: {error}: pip install 'hilrig[fmu]'") from None
    except PlantMapError as error:
        raise pytest.UsageError(str(error)) from None


def _ini_path(config: pytest.Config, name: str) -> Path | None:
    """The ini option's path, relative to the ini file's folder (None: not set)."""
    value = str(config.getini(name) or "").strip()
    if not value:
        return None
    base = config.inipath.parent if config.inipath is not None else config.rootpath
    return (base / value).resolve()


def firmware_choice(config: pytest.Config) -> tuple[Path, str]:
    """The firmware the scenarios start and where that choice comes from: $HIL_FIRMWARE, else
    the ini's `hil_firmware`, else hilrig's default (`hilrig.resources.DEFAULT_FIRMWARE_ORIGIN`).
    No bus wrapper sets any of them: the caller's configuration always wins."""
    variable = resources.FIRMWARE_VARIABLE
    if os.environ.get(variable):
        return Path(os.environ[variable]), f"${variable}"
    configured = _ini_path(config, "hil_firmware")
    if configured is not None:
        where = config.inipath.name if config.inipath is not None else "the ini file"
        return configured, f"hil_firmware of {where}"
    return resources.DEFAULT_FIRMWARE, resources.DEFAULT_FIRMWARE_ORIGIN


def report_header(config: pytest.Config) -> list[str]:
    """The lines a run's header says of its board (none where no hil_* option is set and no
    test asked: a project of no board), so that a log shows which firmware ran."""
    if not any(str(config.getini(name) or "").strip() for name, _ in INI_OPTIONS):
        return []
    firmware, origin = firmware_choice(config)
    table = _ini_path(config, "hil_table") or resources.DEFAULT_TABLE
    bus = os.environ.get(resources.BUS_PATH_VARIABLE)
    lines = [f"hilrig: table {table}", f"hilrig: firmware {firmware} ({origin})"]
    return lines + ([f"hilrig: bus path {bus}"] if bus else [])


def board_from_config(config: pytest.Config) -> HilBoard:
    """The board the ini options describe (see the module docstring)."""
    table_path = _ini_path(config, resources.TABLE_INI_OPTION)
    try:
        files = resources.board_files(table_path)
        table = RigTable.load(files.table) if table_path is not None else RigTable.load()
    except (OSError, TableError) as error:
        raise pytest.UsageError(f"hil_table {table_path}: {error}") from None
    eds = _ini_path(config, "hil_eds") or files.eds
    firmware, _ = firmware_choice(config)
    spelled = str(config.getini("hil_plant") or "").strip()
    plant_map = _ini_path(config, "hil_plant_map")
    if spelled.endswith(".fmu") or plant_map is not None:
        plant = fmu_plant_factory(_ini_path(config, "hil_plant"), plant_map, table)
    else:
        plant = load_factory(spelled) if spelled else default_plant
    args = tuple(shlex.split(str(config.getini("hil_firmware_args") or "")))
    dashboard = "overview" if resources.is_default_table(files.table) else GENERATED_DASHBOARD
    return HilBoard(
        table=table, eds=eds, firmware=firmware, plant=plant, firmware_args=args, dashboard=dashboard
    )


__all__ = ["INI_OPTIONS", "HilBoard", "board_from_config", "firmware_choice", "load_factory", "report_header"]
