"""The standard blocks (boardproto.standard): what a table gets without writing it, how a board's
own blocks override them, and the kind of field no component writes."""

from __future__ import annotations

import re
import subprocess
import sys
import tomllib
from collections.abc import Callable
from pathlib import Path

import pytest

from boardproto import Kind, TableError, load_table
from boardproto.loader import ACTUATOR_FIELD_FIX
from boardproto.standard import (
    STANDARD_PDO_SLOTS,
    STANDARD_TABLE,
    STANDARD_TRANSMISSION_TYPES,
    merge_standard,
    standard_document,
)
from boardproto.table import PdoDirection

TableWriter = Callable[[str], Path]
PROTOCOL_DIR = Path(__file__).resolve().parents[1]
LAMP_TABLE = PROTOCOL_DIR.parent / "examples" / "other-project" / "board.toml"

# What a board must write: its identity, its fields, its HIL I/O and its PDOs.
SMALLEST_TABLE = """\
[node]
vendor_id = 0x1234
product_code = 0x5678
revision = 0x00010000
device_name = "fan"
hardware_version = "hw"
software_version = "sw"
default_node_id = 0x21

[[field]]
name = "fan_speed"
index = 0x2000
unit = "rad/s"
kind = "sensor"
access = "ro"
min = 0.0
max = 1000.0
default = 0.0
stored = false
description = "Fan speed from the tachometer"

[[hil_input]]
name = "tach_period"
index = 0x3000
type = "unsigned16"
min = 0
max = 65535
unit = "count"
description = "Tachometer period"

[[hil_output]]
name = "fan_pwm"
index = 0x3100
type = "unsigned16"
min = 0
max = 10000
unit = "0.01%"
description = "Fan PWM duty"

[[rpdo]]
number = 1
map = ["tach_period"]

[[tpdo]]
number = 1
map = ["fan_pwm", "fan_speed"]
"""
PDO_SECTION = "\n[[rpdo]]\nnumber = 1\n"
"""Where SMALLEST_TABLE's PDOs start: board-level tables go before it."""


def _with(addition: str) -> str:
    """SMALLEST_TABLE with `addition` (top-level tables and arrays) before its PDOs."""
    head, pdos = SMALLEST_TABLE.split(PDO_SECTION, 1)
    return f"{head}\n{addition}{PDO_SECTION}{pdos}"


def _emcy(name: str, code: int, description: str = "d") -> str:
    return (
        f'[[emcy]]\nname = "{name}"\ncode = 0x{code:04X}\n'
        f'error_register = "generic"\ndescription = "{description}"\n\n'
    )


def refused(path: Path, *fragments: str) -> str:
    with pytest.raises(TableError) as caught:
        load_table(path)
    message = str(caught.value)
    assert message.startswith(f"{path}: "), message
    for fragment in fragments:
        assert fragment in message, f"expected {fragment!r} in {message!r}"
    assert "\n" not in message
    return message


STANDARD = standard_document()
STANDARD_EMCY = [e["name"] for e in STANDARD["emcy"]]
STANDARD_CODES = {e["name"]: e["code"] for e in STANDARD["emcy"]}


def test_the_smallest_table_gets_every_standard_block(write_table: TableWriter) -> None:
    table = load_table(write_table(SMALLEST_TABLE))
    node = STANDARD["node"]
    assert (
        table.node.device_type,
        table.node.heartbeat_ms,
        table.node.error_history_length,
        table.node.heartbeat_consumers,
    ) == (
        node["device_type"],
        node["heartbeat_ms"],
        node["error_history_length"],
        node["heartbeat_consumers"],
    )
    assert [e.name for e in table.emcy_codes] == STANDARD_EMCY
    assert [(e.code, e.description) for e in table.emcy_codes] == [
        (e["code"], e["description"]) for e in STANDARD["emcy"]
    ]
    assert [e.name for e in table.enums] == [e["name"] for e in STANDARD["enum"]]
    assert table.recorder is not None
    assert table.recorder.index == STANDARD["recorder"]["index"]
    assert (len(table.rpdos), len(table.tpdos)) == (STANDARD_PDO_SLOTS, STANDARD_PDO_SLOTS)
    assert table.rpdo(1).transmission_type == STANDARD_TRANSMISSION_TYPES[PdoDirection.RPDO]
    assert table.tpdo(1).transmission_type == STANDARD_TRANSMISSION_TYPES[PdoDirection.TPDO]
    assert not table.rpdo(2).enabled


@pytest.mark.parametrize(
    "identity",
    [
        "vendor_id",
        "product_code",
        "revision",
        "device_name",
        "hardware_version",
        "software_version",
        "default_node_id",
    ],
)
def test_the_identity_has_no_default(identity: str, write_table: TableWriter) -> None:
    lines = [
        line for line in SMALLEST_TABLE.splitlines(keepends=True) if not line.startswith(f"{identity} =")
    ]
    refused(write_table("".join(lines)), "node: missing key", identity)


def test_a_node_key_of_the_board_replaces_only_that_key(write_table: TableWriter) -> None:
    text = SMALLEST_TABLE.replace(
        "default_node_id = 0x21\n", "default_node_id = 0x21\nheartbeat_consumers = 3\n"
    )
    node = load_table(write_table(text)).node
    assert node.heartbeat_consumers == 3
    assert node.heartbeat_ms == STANDARD["node"]["heartbeat_ms"]


def test_the_boards_own_codes_come_first_then_the_standard_ones(write_table: TableWriter) -> None:
    table = load_table(write_table(_with(_emcy("fan_stalled", 0x5010))))
    assert [e.name for e in table.emcy_codes] == ["fan_stalled", *STANDARD_EMCY]


def test_a_code_of_a_standard_name_replaces_it_at_the_boards_place(write_table: TableWriter) -> None:
    late = _emcy("rpdo_timeout", STANDARD_CODES["rpdo_timeout"], "The tachometer's RPDO is late")
    own = _emcy("fan_stalled", 0x5010) + late
    table = load_table(write_table(_with(own)))
    names = [e.name for e in table.emcy_codes]
    assert names == ["fan_stalled", "rpdo_timeout", *(n for n in STANDARD_EMCY if n != "rpdo_timeout")]
    assert table.emcy("rpdo_timeout").description == "The tachometer's RPDO is late"


def test_refuses_a_standard_code_under_another_name(write_table: TableWriter) -> None:
    code = STANDARD_CODES["receive_overrun"]
    refused(
        write_table(_with(_emcy("lost_frames", code))),
        f"emcy 'lost_frames': code 0x{code:04X} is the standard 'receive_overrun''s",
        "name yours 'receive_overrun' to replace it",
    )


def test_a_fault_bit_raises_a_standard_code_the_table_does_not_write(write_table: TableWriter) -> None:
    bits = (
        '[[bitset]]\nname = "fault_flags"\ndescription = "Faults"\n\n'
        '[[bitset.bits]]\nname = "tach_stale"\nbit = 0\nemcy = "stale_sensor"\nabout = "fan_speed"\n'
        'description = "No tachometer sample"\n\n'
    )
    table = load_table(write_table(_with(bits)))
    assert table.bitset("fault_flags").bit("tach_stale").emcy == "stale_sensor"


def test_pdo_slots_grow_to_the_highest_configured_number(write_table: TableWriter) -> None:
    text = SMALLEST_TABLE + '\n[[tpdo]]\nnumber = 6\nmap = ["fan_speed"]\n'
    table = load_table(write_table(text))
    assert (len(table.rpdos), len(table.tpdos)) == (STANDARD_PDO_SLOTS, 6)
    profile = (
        '\n[[pdo_profile]]\nname = "wide"\ndescription = "d"\n\n'
        '[[pdo_profile.rpdo]]\nnumber = 7\ncob_id_base = 0x600\nmap = ["tach_period"]\n'
    )
    assert len(load_table(write_table(SMALLEST_TABLE + profile)).rpdos) == 7


def test_pdo_section_sets_the_slots(write_table: TableWriter) -> None:
    table = load_table(write_table(_with("[pdo]\nrpdo_slots = 1\ntpdo_slots = 2\n")))
    assert (len(table.rpdos), len(table.tpdos)) == (1, 2)


def test_a_pdo_transmission_type_of_the_board_wins(write_table: TableWriter) -> None:
    text = SMALLEST_TABLE.replace(
        'map = ["fan_pwm", "fan_speed"]', 'transmission_type = 10\nmap = ["fan_pwm", "fan_speed"]'
    )
    assert load_table(write_table(text)).tpdo(1).transmission_type == 10


def test_refuses_a_field_of_kind_actuator_saying_what_to_use(write_table: TableWriter) -> None:
    text = SMALLEST_TABLE.replace('kind = "sensor"', 'kind = "actuator"')
    message = refused(write_table(text), "field 'fan_speed'", ACTUATOR_FIELD_FIX)
    assert "[[hil_output]]" in message and "module field" in message and "command field" in message


def test_every_other_kind_has_a_writer(write_table: TableWriter) -> None:
    """The firmware's rule: a component writes only fields of its own kind, an Actuator none, the
    bus only rw fields. Every kind but actuator loads."""
    access = {Kind.COMMAND: "rw", Kind.PARAMETER: "rw"}
    for kind in Kind:
        if kind is Kind.ACTUATOR:
            continue
        text = SMALLEST_TABLE.replace(
            'kind = "sensor"\naccess = "ro"', f'kind = "{kind}"\naccess = "{access.get(kind, "ro")}"'
        )
        assert load_table(write_table(text)).field("fan_speed").kind is kind


def test_merge_leaves_malformed_blocks_for_the_loader_to_refuse(write_table: TableWriter) -> None:
    assert merge_standard({"node": 3, "emcy": "x"})["node"] == 3
    assert len(merge_standard({"emcy": [{"name": ["x"]}, 1]})["emcy"]) == 2 + len(STANDARD_EMCY)
    refused(write_table('emcy = "none"\n' + SMALLEST_TABLE), "emcy must be an array of tables")
    refused(write_table(_with("[recorder]\nchanels = 4\n")), "recorder: unknown key 'chanels'")


def test_the_lamps_table_holds_only_its_own() -> None:
    """The example a new board copies writes none of the standard blocks."""
    with LAMP_TABLE.open("rb") as file:
        document = tomllib.load(file)
    assert not {"emcy", "enum", "recorder", "pdo"} & document.keys()
    assert not set(STANDARD["node"]) & document["node"].keys()
    load_table(LAMP_TABLE)


def test_the_minimal_table_of_protocol_readme_loads(write_table: TableWriter) -> None:
    readme = (PROTOCOL_DIR / "README.md").read_text()
    examples = re.findall(r"```toml\n(.*?)```", readme, re.S)
    assert len(examples) == 1, "protocol/README.md shows one minimal table"
    table = load_table(write_table(examples[0]))
    assert [e.name for e in table.emcy_codes] == STANDARD_EMCY


def test_the_command_prints_the_standard_table() -> None:
    result = subprocess.run(
        [sys.executable, "-m", "boardproto", "standard"],
        cwd=PROTOCOL_DIR,
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout == STANDARD_TABLE
    assert tomllib.loads(result.stdout) == STANDARD
