"""The DBC loads in cantools and decodes the frames the firmware and the rig send, with the
table's named values."""

from __future__ import annotations

import math
import struct
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import cantools
import pytest
from cantools.database.can import Database

from boardproto import BoardTable, load_table
from boardproto.cia301 import FunctionCode, cob_id
from boardproto.dbc import MAX_COMBINED_BITS, build_database, node_id_warning, value_choices
from boardproto.table import BitSet, FlagBit

# Every fault value below comes from the table: moving a bit in board.toml moves them too.
TABLE = load_table(Path(__file__).resolve().parents[1] / "board.toml")
FAULTS = TABLE.bitset("fault_flags")
ENCODERS_STALE = sorted(
    (FAULTS.bit("motor_encoder_stale"), FAULTS.bit("output_encoder_stale")), key=lambda b: b.bit
)
ENCODERS_STALE_FLAGS = ENCODERS_STALE[0].mask | ENCODERS_STALE[1].mask
ENCODERS_STALE_NAME = f"{ENCODERS_STALE[0].name}|{ENCODERS_STALE[1].name}"


@pytest.fixture(scope="module")
def dbc_path(generated_dir: Path) -> Path:
    return generated_dir / "board.dbc"


@pytest.fixture(scope="module")
def database(dbc_path: Path) -> Database:
    loaded = cantools.database.load_file(dbc_path)
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
    message = database.get_message_by_frame_id(cob_id(FunctionCode.TPDO1, 0x10))
    assert message.name == "TPDO1"
    assert message.decode(frame, decode_choices=False) == {"motor_duty": -2500, "led_pattern": 3}
    assert message.decode(frame) == {"motor_duty": -2500, "led_pattern": "fast_blink"}


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


# --- named values ----------------------------------------------------------------------
def test_every_signal_with_values_has_their_value_table(database: Database, table: BoardTable) -> None:
    named = set()
    for message in database.messages:
        for signal in message.signals:
            values = table.values_of(signal.name)
            if values is None:
                assert signal.choices is None, signal.name
                continue
            named.add(signal.name)
            assert signal.choices is not None, signal.name
            assert {n: str(v) for n, v in signal.choices.items()} == {
                n: v.name for n, v in value_choices(values).items()
            }, signal.name
    assert named == {"control_mode", "led_pattern", "fault_flags"}  # the mapped ones today


def test_an_enum_names_each_of_its_values(database: Database, table: BoardTable) -> None:
    choices = database.get_message_by_name("RPDO3").get_signal_by_name("control_mode").choices
    assert choices is not None
    names = {n: str(v) for n, v in choices.items()}
    assert names == {v.value: v.name for v in table.enum("control_mode").values}
    assert names == {0: "disabled", 1: "velocity", 2: "torque", 3: "position"}


def test_a_bitset_names_none_each_bit_and_each_combination(database: Database, table: BoardTable) -> None:
    choices = database.get_message_by_name("TPDO6").get_signal_by_name("fault_flags").choices
    assert choices is not None
    names = {n: str(v) for n, v in choices.items()}
    bits = table.bitset("fault_flags").bits
    assert len(bits) <= MAX_COMBINED_BITS
    assert len(names) == 2 ** len(bits)
    assert names[0] == "none"
    assert {bit.mask: names[bit.mask] for bit in bits} == {bit.mask: bit.name for bit in bits}
    assert names[ENCODERS_STALE_FLAGS] == ENCODERS_STALE_NAME
    by_bit = sorted(bits, key=lambda b: b.bit)
    assert names[by_bit[0].mask | by_bit[-1].mask] == f"{by_bit[0].name}|{by_bit[-1].name}"


def test_a_bitset_too_wide_to_combine_names_its_single_bits() -> None:
    width = MAX_COMBINED_BITS + 1
    wide = BitSet("wide", "", tuple(FlagBit(f"b{n}", n, "", None, None) for n in range(width)))
    names = {n: v.name for n, v in value_choices(wide).items()}
    assert names == {0: "none", **{1 << n: f"b{n}" for n in range(width)}}


def test_a_real32_enum_of_1_0_decodes_to_its_name(database: Database) -> None:
    message = database.get_message_by_name("RPDO3")  # control_mode, position_setpoint: REAL32
    frame = struct.pack("<ff", 1.0, 0.25)
    decoded = message.decode(frame)
    assert str(decoded["control_mode"]) == "velocity"
    assert decoded["position_setpoint"] == 0.25
    assert message.decode(frame, decode_choices=False) == {"control_mode": 1.0, "position_setpoint": 0.25}
    assert message.encode({"control_mode": "velocity", "position_setpoint": 0.25}) == frame


def test_a_real32_bitset_decodes_to_the_names_of_its_bits(database: Database) -> None:
    message = database.get_message_by_name("TPDO6")  # safe_state, fault_flags: REAL32
    assert str(message.decode(struct.pack("<ff", 1.0, ENCODERS_STALE_FLAGS))["fault_flags"]) == (
        ENCODERS_STALE_NAME
    )
    assert str(message.decode(struct.pack("<ff", 0.0, 0.0))["fault_flags"]) == "none"
    unnamed = float(1 << max(b.bit for b in FAULTS.bits) + 1)
    assert message.decode(struct.pack("<ff", 1.0, unnamed))["fault_flags"] == unnamed  # no such bit (yet)


def test_without_choices_a_real32_decodes_to_its_exact_number(database: Database) -> None:
    """What the rig relies on: decode_choices=False passes any float through, NaN included
    (cantools 45 looks a float's choice up by int(value), which NaN makes raise)."""
    message = database.get_message_by_name("RPDO3")
    decoded = message.decode(struct.pack("<ff", math.nan, 0.0), decode_choices=False)
    assert math.isnan(decoded["control_mode"])
    assert message.decode(struct.pack("<ff", 1.5, 0.0), decode_choices=False)["control_mode"] == 1.5


def test_value_tables_are_written_as_val_lines_and_float_types(dbc_path: Path, database: Database) -> None:
    text = dbc_path.read_text()
    rpdo3 = database.get_message_by_name("RPDO3").frame_id
    assert f'VAL_ {rpdo3} control_mode 0 "disabled" 1 "velocity" 2 "torque" 3 "position" ;' in text
    assert f"SIG_VALTYPE_ {rpdo3} control_mode : 1;" in text  # IEEE float, as before
    tpdo6 = database.get_message_by_name("TPDO6").frame_id
    lowest = sorted(FAULTS.bits, key=lambda b: b.bit)[:2]
    assert f'VAL_ {tpdo6} fault_flags 0 "none" {lowest[0].mask} "{lowest[0].name}" ' in text
    assert f' {lowest[1].mask} "{lowest[1].name}" ' in text


def test_cantools_decode_prints_the_names_in_a_candump_log(dbc_path: Path, tmp_path: Path) -> None:
    """`python -m cantools decode board.dbc < candump.log`, what a person at a bench types."""
    status = struct.pack("<ff", 1.0, ENCODERS_STALE_FLAGS).hex().upper()  # safe_state, fault_flags
    log = (
        "(1700000000.000000) vcan0 410#0000803F00000000\n"  # RPDO3: control_mode 1.0
        f"(1700000000.001000) vcan0 2D0#{status}\n"  # TPDO6
        "(1700000000.002000) vcan0 190#E80302\n"  # TPDO1: motor_duty 1000, led_pattern 2
    )
    result = subprocess.run(
        [sys.executable, "-m", "cantools", "decode", "--single-line", str(dbc_path)],
        input=log,
        capture_output=True,
        text=True,
        check=True,
        timeout=60,
    )
    lines = result.stdout.splitlines()
    assert lines[0].endswith(":: RPDO3(control_mode: velocity, position_setpoint: 0.0 rad)")
    assert f"fault_flags: {ENCODERS_STALE_NAME}" in lines[1]
    assert "led_pattern: slow_blink" in lines[2]


# --- node ids --------------------------------------------------------------------------
def test_another_node_id_moves_every_frame_id(table: BoardTable) -> None:
    default = build_database(table)
    other = build_database(table, node_id=0x21)
    shift = 0x21 - table.node.default_node_id
    assert [m.name for m in other.messages] == [m.name for m in default.messages]
    for moved, original in zip(other.messages, default.messages, strict=True):
        assert moved.frame_id == original.frame_id + shift, moved.name
        assert moved.comment is not None and "node 0x21" in moved.comment
        assert [s.name for s in moved.signals] == [s.name for s in original.signals]
    dumped = cantools.database.load_string(other.as_dbc_string(), "dbc")
    assert {m.frame_id for m in dumped.messages} == {m.frame_id for m in other.messages}


def test_node_ids_above_63_are_warned_about_when_pdo_5_to_8_keep_default_cob_ids(table: BoardTable) -> None:
    assert node_id_warning(table, table.node.default_node_id) is None
    assert node_id_warning(table, 63) is None
    warning = node_id_warning(table, 0x50)
    assert warning is not None
    assert "TPDO5 0x210 = RPDO1 of node 0x10" in warning
    assert "TPDO8 0x510 = RPDO4 of node 0x10" in warning
    assert "below 64" in warning


def test_no_warning_without_pdo_5_to_8(write_table: Callable[[str], Path], minimal_table: str) -> None:
    small = load_table(write_table(minimal_table))
    assert node_id_warning(small, 0x50) is None
