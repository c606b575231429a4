"""The DBC loads in cantools and decodes the frames the firmware and the rig send."""

from __future__ import annotations

import struct
from pathlib import Path

import cantools
import pytest
from cantools.database.can import Database

from boardproto import BoardTable


@pytest.fixture(scope="module")
def database(generated_dir: Path) -> Database:
    loaded = cantools.database.load_file(generated_dir / "board.dbc")
    assert isinstance(loaded, Database)
    return loaded


def test_one_message_per_enabled_default_pdo(database: Database, table: BoardTable) -> None:
    expected = {
        (p.name, p.cob_id(table.node.default_node_id), p.length_bytes)
        for p in table.pdos
        if p.enabled and p.entries
    }
    assert {(m.name, m.frame_id, m.length) for m in database.messages} == expected
    assert "RPDO4" not in {m.name for m in database.messages}


def test_decodes_actuator_tpdo_as_the_firmware_packs_it(database: Database) -> None:
    frame = struct.pack("<hB", -2500, 3)  # motor_duty I16, led_pattern U8, little-endian
    message = database.get_message_by_frame_id(0x190)
    assert message.name == "TPDO1"
    assert message.decode(frame) == {"motor_duty": -2500, "led_pattern": 3}


def test_decodes_real32_trace_tpdo(database: Database) -> None:
    frame = struct.pack("<ff", 12.5, -0.375)
    decoded = database.get_message_by_name("TPDO2").decode(frame)
    assert decoded == {"motor_velocity": 12.5, "output_velocity": -0.375}


def test_encodes_sensor_rpdo_as_the_firmware_unpacks_it(database: Database) -> None:
    values = {
        "motor_encoder_counts": 65535,
        "output_encoder_counts": 1234,
        "thermistor_adc": 2048,
        "motor_current_adc": -1500,
    }
    frame = database.get_message_by_name("RPDO1").encode(values)
    assert frame == struct.pack("<HHHh", 65535, 1234, 2048, -1500)


def test_signals_carry_units_limits_and_types(database: Database, table: BoardTable) -> None:
    for message in database.messages:
        for signal in message.signals:
            entry = table.entry(signal.name)
            assert signal.unit == entry.unit, signal.name
            assert (signal.minimum, signal.maximum) == (entry.min, entry.max), signal.name
            assert signal.is_float == (entry.data_type.name == "REAL32"), signal.name
            assert signal.is_signed == entry.data_type.is_signed, signal.name
            assert signal.byte_order == "little_endian"
            assert (signal.scale, signal.offset) == (1, 0)
