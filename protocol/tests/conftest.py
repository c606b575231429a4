"""Shared fixtures: the real board table, its generated outputs, and a small valid
table that the validation tests break one way at a time."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from boardproto import BoardTable, load_table
from boardproto.cli import generate

PROTOCOL_DIR = Path(__file__).resolve().parents[1]
BOARD_TOML = PROTOCOL_DIR / "board.toml"

# Smallest table that exercises every section; tests replace one piece of it.
MINIMAL_TABLE = """\
[node]
device_type = 0
vendor_id = 0x1234
product_code = 0x5678
revision = 0x00010000
device_name = "test-node"
hardware_version = "hw"
software_version = "sw"
default_node_id = 0x10
heartbeat_ms = 100
error_history_length = 4
heartbeat_consumers = 1

[[field]]
name = "motor_position"
index = 0x2000
unit = "rad"
kind = "sensor"
access = "ro"
min = -10.0
max = 10.0
default = 0.0
stored = false
description = "Motor angle"

[[field]]
name = "velocity_kp"
index = 0x2500
unit = "1/(rad/s)"
kind = "parameter"
access = "rw"
min = 0.0
max = 1.0
default = 0.05
stored = true
description = "Gain"

[[hil_input]]
name = "motor_encoder_counts"
index = 0x3000
type = "unsigned16"
min = 0
max = 65535
unit = "count"
description = "Encoder counter"

[[hil_output]]
name = "motor_duty"
index = 0x3100
type = "integer16"
min = -10000
max = 10000
unit = "0.01%"
description = "Duty"

[pdo]
rpdo_slots = 2
tpdo_slots = 2

[[rpdo]]
number = 1
transmission_type = 255
map = ["motor_encoder_counts", "velocity_kp"]

[[tpdo]]
number = 1
transmission_type = 1
map = ["motor_duty", "motor_position"]
"""


@pytest.fixture
def minimal_table() -> str:
    return MINIMAL_TABLE


@pytest.fixture(scope="session")
def table() -> BoardTable:
    return load_table(BOARD_TOML)


@pytest.fixture(scope="session")
def generated_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out_dir = tmp_path_factory.mktemp("generated")
    generate(BOARD_TOML, out_dir)
    return out_dir


@pytest.fixture
def write_table(tmp_path: Path) -> Callable[[str], Path]:
    """Write TOML text to tmp_path/board.toml and return its path."""

    def write(text: str) -> Path:
        path = tmp_path / "board.toml"
        path.write_text(text)
        return path

    return write


@pytest.fixture
def edit_table(write_table: Callable[[str], Path]) -> Callable[[str, str], Path]:
    """Replace one exact piece of the minimal table, write it, return its path."""

    def edit(old: str, new: str) -> Path:
        assert MINIMAL_TABLE.count(old) == 1, f"test setup: {old!r} must occur exactly once"
        return write_table(MINIMAL_TABLE.replace(old, new))

    return edit
