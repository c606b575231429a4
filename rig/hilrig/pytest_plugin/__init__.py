"""hilrig's pytest plugin (entry point `pytest11`): hardware-in-the-loop scenarios for any board.

A project installs hilrig, says what its board is in its pytest configuration (its table, its
firmware, its plant: `board`), and its tests get the fixtures (`fixtures`): `make_scenario`
(the firmware on a private vcan, a `Rig` with the board's plant, a bus log and a trace),
`make_robot`, `private_bus`, `scenario_dir`, `hil_board`, with the `--hil-*` options (a real
board on a real interface, a live viewer); `run_hilrig` runs the `hilrig` command on a test's
bus; with labgrid's `--lg-env` the board, its bus, power and console come from a labgrid target
(`labgrid`). Every lockstep run is compared with its approved trace beside the tests
(`--hil-approved`, `approved`). A failure names its evidence, its picture and, with
`--hil-baseline`, the comparison with the last good run (`reports`).
`@pytest.mark.requirement("ID", ...)` names what a test verifies, checked against the project's
requirements file and exported as JUnit properties and needs.json (`requirements`).

    # pytest.ini
    [pytest]
    hil_table = board.toml
    hil_firmware = build/toy-firmware
    hil_plant = toy_plant:make_plant

    # test_toy.py
    def test_the_lamp_follows_its_command(make_scenario):
        s = make_scenario(seed=1)
        ...

A top layer beside the CLI: it imports the session, the engine and the observers, nothing imports
it. Hooks and fixtures do nothing until a test asks for them (every pytest run of an environment
with hilrig installed loads the plugin).
"""

import pytest

# The parts are plugins of their own (`pytest_plugins` below), imported here first: their
# asserts are rewritten like any plugin's.
pytest.register_assert_rewrite(
    "hilrig.pytest_plugin.approved",
    "hilrig.pytest_plugin.board",
    "hilrig.pytest_plugin.fixtures",
    "hilrig.pytest_plugin.labgrid",
    "hilrig.pytest_plugin.reports",
    "hilrig.pytest_plugin.requirements",
)

from hilrig.pytest_plugin.board import HilBoard, board_from_config, load_factory  # noqa: E402
from hilrig.pytest_plugin.fixtures import (  # noqa: E402
    BOOT_TIMEOUT_S,
    REALTIME_FIRMWARE_PERIOD_US,
    REALTIME_RIG_PERIOD_US,
    SCENARIO_SDO_TIMEOUT_S,
    Scenario,
    output_root,
    run_hilrig,
)
from hilrig.pytest_plugin.reports import ATTACHMENT, baseline_path  # noqa: E402

pytest_plugins = [
    "hilrig.pytest_plugin.reports",
    "hilrig.pytest_plugin.approved",
    "hilrig.pytest_plugin.fixtures",
    "hilrig.pytest_plugin.labgrid",
    "hilrig.pytest_plugin.requirements",
]
"""The plugin's parts, registered with it (their hooks and fixtures)."""

__all__ = [
    "ATTACHMENT",
    "BOOT_TIMEOUT_S",
    "REALTIME_FIRMWARE_PERIOD_US",
    "REALTIME_RIG_PERIOD_US",
    "SCENARIO_SDO_TIMEOUT_S",
    "HilBoard",
    "Scenario",
    "baseline_path",
    "board_from_config",
    "load_factory",
    "output_root",
    "run_hilrig",
]
