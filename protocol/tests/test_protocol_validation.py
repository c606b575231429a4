"""One test per validation rule: a small bad table must be refused with a message
that names the file, the entry and the problem."""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

import pytest

from boardproto import Access, TableError, load_table
from boardproto.standard import standard_document

TableWriter = Callable[[str], Path]  # TOML text -> path
TableEditor = Callable[[str, str], Path]  # (old, new) -> path of the edited minimal table

FIELD_ENTRY_END = 'description = "Motor angle"\n'


def refused(path: Path, *fragments: str) -> str:
    """Load path, expect TableError naming the file and every fragment; return the message."""
    with pytest.raises(TableError) as caught:
        load_table(path)
    message = str(caught.value)
    assert message.startswith(f"{path}: "), message
    for fragment in fragments:
        assert fragment in message, f"expected {fragment!r} in {message!r}"
    assert "\n" not in message
    return message


def test_minimal_table_is_valid(minimal_table: str, write_table: TableWriter) -> None:
    table = load_table(write_table(minimal_table))
    assert [f.name for f in table.fields] == ["motor_position", "velocity_kp"]
    assert table.rpdo(1).bits == 48


def test_the_control_period_and_its_range_come_from_the_standard_node_block(
    minimal_table: str, write_table: TableWriter
) -> None:
    node = load_table(write_table(minimal_table)).node
    assert (node.period_us_min, node.period_us, node.period_us_max) == (100, 1000, 1_000_000)


def test_the_boot_time_comes_from_the_standard_node_block_and_a_board_may_set_its_own(
    minimal_table: str, write_table: TableWriter, edit_table: TableEditor
) -> None:
    assert load_table(write_table(minimal_table)).node.boot_ms == 20
    at_once = edit_table("default_node_id = 0x10", "default_node_id = 0x10\nboot_ms = 0")
    assert load_table(at_once).node.boot_ms == 0
    refused(
        edit_table("default_node_id = 0x10", "default_node_id = 0x10\nboot_ms = -1"),
        "node: boot_ms -1 outside 0..",
    )


def test_refuses_a_control_period_outside_its_range(edit_table: TableEditor) -> None:
    refused(
        edit_table("default_node_id = 0x10", "default_node_id = 0x10\nperiod_us = 50"),
        "node: period_us 50 outside 100..",
    )
    refused(
        edit_table("default_node_id = 0x10", "default_node_id = 0x10\nperiod_us_min = 0"),
        "period_us_min 0 outside 1..",
    )


def test_refuses_duplicate_name(edit_table: TableEditor) -> None:
    refused(
        edit_table('name = "velocity_kp"', 'name = "motor_position"'),
        "field 'motor_position'",
        "duplicate name",
    )


def test_refuses_name_shared_by_field_and_hil_io(edit_table: TableEditor) -> None:
    refused(
        edit_table('name = "motor_duty"', 'name = "velocity_kp"'),
        "hil_output 'velocity_kp'",
        "duplicate name",
    )


def test_refuses_duplicate_index(edit_table: TableEditor) -> None:
    refused(
        edit_table("index = 0x2500", "index = 0x2000"),
        "field 'velocity_kp'",
        "index 0x2000 already used by 'motor_position'",
    )


def test_refuses_default_outside_range(edit_table: TableEditor) -> None:
    refused(
        edit_table("default = 0.05", "default = 1.5"),
        "field 'velocity_kp'",
        "default 1.5 outside [0.0, 1.0]",
    )


def test_refuses_min_greater_than_max(edit_table: TableEditor) -> None:
    refused(
        edit_table("min = -10.0\nmax = 10.0", "min = 20.0\nmax = 10.0"),
        "field 'motor_position'",
        "min 20.0 is greater than max 10.0",
    )


def test_refuses_limit_that_is_not_a_float32(edit_table: TableEditor) -> None:
    refused(
        edit_table("max = 10.0", "max = 1e39"),
        "field 'motor_position'",
        "max 1e+39 is not a finite 32-bit float",
    )


def test_refuses_pdo_longer_than_64_bits(edit_table: TableEditor) -> None:
    refused(
        edit_table(
            'map = ["motor_duty", "motor_position"]',
            'map = ["motor_duty", "motor_position", "velocity_kp"]',
        ),
        "TPDO1",
        "80 bits long",
        "at most 64 bits",
    )


def test_refuses_pdo_mapping_unknown_object(edit_table: TableEditor) -> None:
    refused(
        edit_table('map = ["motor_duty", "motor_position"]', 'map = ["motor_duty", "motor_postion"]'),
        "TPDO1",
        "unknown object",
        "'motor_postion'",
        "did you mean 'motor_position'",
    )


def test_refuses_rpdo_mapping_read_only_object(edit_table: TableEditor) -> None:
    refused(
        edit_table('map = ["motor_encoder_counts", "velocity_kp"]', 'map = ["motor_position"]'),
        "RPDO1",
        "'motor_position'",
        "read-only",
    )


def test_refuses_pdo_number_beyond_slots(minimal_table: str, write_table: TableWriter) -> None:
    text = minimal_table + "\n[[tpdo]]\nnumber = 3\ntransmission_type = 1\nmap = []\n"
    refused(write_table(text), "TPDO3", "number 3 outside 1..2")


def test_refuses_unknown_kind(edit_table: TableEditor) -> None:
    refused(
        edit_table('kind = "sensor"', 'kind = "sensr"'),
        "field 'motor_position'",
        "unknown kind 'sensr'",
        "sensor",
    )


def test_refuses_unknown_access(edit_table: TableEditor) -> None:
    refused(
        edit_table('access = "ro"', 'access = "wo"'),
        "field 'motor_position'",
        "unknown access 'wo'",
    )


def test_refuses_access_that_contradicts_kind(edit_table: TableEditor) -> None:
    refused(
        edit_table('access = "ro"', 'access = "rw"'),
        "field 'motor_position'",
        "a sensor field must have access 'ro'",
    )


def test_refuses_unknown_hil_type(edit_table: TableEditor) -> None:
    refused(
        edit_table('type = "unsigned16"', 'type = "uint16"'),
        "hil_input 'motor_encoder_counts'",
        "unknown type 'uint16'",
    )


def test_refuses_hil_range_outside_its_type(edit_table: TableEditor) -> None:
    refused(
        edit_table("max = 65535", "max = 65536"),
        "hil_input 'motor_encoder_counts'",
        "max 0x10000 outside",
    )


def test_refuses_index_outside_manufacturer_range(edit_table: TableEditor) -> None:
    refused(
        edit_table("index = 0x2500", "index = 0x1F00"),
        "field 'velocity_kp'",
        "0x1F00",
        "outside the manufacturer range 0x2000..0x5FFF",
    )


@pytest.mark.parametrize(
    "bad_name", ["MotorPosition", "motor-position", "motor__position", "_motor", "2motor"]
)
def test_refuses_name_that_is_not_snake_case(edit_table: TableEditor, bad_name: str) -> None:
    refused(
        edit_table('name = "motor_position"', f'name = "{bad_name}"'),
        f"name {bad_name!r} is not snake_case",
    )


def test_refuses_cpp_keyword_as_name(edit_table: TableEditor) -> None:
    refused(edit_table('name = "motor_position"', 'name = "default"'), "field 'default'", "C++ keyword")


def test_refuses_unknown_key_with_suggestion(edit_table: TableEditor) -> None:
    refused(
        edit_table(FIELD_ENTRY_END, FIELD_ENTRY_END + "defualt = 1.0\n"),
        "field 'motor_position'",
        "unknown key 'defualt'",
        "did you mean 'default'",
    )


def test_refuses_missing_key(edit_table: TableEditor) -> None:
    refused(edit_table('unit = "rad"\n', ""), "field 'motor_position'", "missing key unit")


def test_a_field_without_access_default_or_stored_takes_its_kinds_and_zero(edit_table: TableEditor) -> None:
    path = edit_table(
        'access = "ro"\nmin = -10.0\nmax = 10.0\ndefault = 0.0\nstored = false\n', "min = 1.0\nmax = 10.0\n"
    )
    field = load_table(path).field("motor_position")
    assert (field.access, field.default, field.stored) == (Access.READ_ONLY, 1.0, False)  # 0 outside: min


def test_an_access_other_than_the_kinds_is_still_refused(edit_table: TableEditor) -> None:
    refused(edit_table('access = "ro"\n', 'access = "rw"\n'), "a sensor field must have access 'ro'")


def test_only_a_command_field_is_in_the_setpoint_stream(edit_table: TableEditor) -> None:
    # motor_position, the first field, is a sensor: the board writes it, no master streams it.
    streamed_sensor = edit_table("stored = false\n", "stored = false\nstream = true\n")
    refused(streamed_sensor, "only command fields are streamed")
    assert load_table(edit_table("stored = false\n", "stored = false\n")).setpoint_stream == ()


@pytest.mark.parametrize("count", [0, 5])
def test_refuses_heartbeat_consumer_count_outside_its_range(edit_table: TableEditor, count: int) -> None:
    refused(
        edit_table("heartbeat_consumers = 1\n", f"heartbeat_consumers = {count}\n"),
        "node: ",
        f"heartbeat_consumers {count} outside 1..4",
    )


def test_refuses_node_without_its_identity(edit_table: TableEditor) -> None:
    refused(edit_table("product_code = 0x5678\n", ""), "node: ", "missing key product_code")


def test_refuses_unknown_top_level_table(minimal_table: str, write_table: TableWriter) -> None:
    text = minimal_table.replace("[[field]]", "[[fields]]", 1)
    refused(write_table(text), "unknown top-level table 'fields'", "did you mean 'field'")


def test_refuses_invalid_toml(edit_table: TableEditor) -> None:
    refused(edit_table("stored = true", "stored = "), "not valid TOML")


def test_refuses_missing_file(tmp_path: Path) -> None:
    message = refused(tmp_path / "absent.toml", "cannot read")
    assert re.search(r"No such file", message)


def test_refuses_bytes_that_are_not_utf8(minimal_table: str, tmp_path: Path) -> None:
    # Found by protocol/fuzz/fuzz_table.py: tomllib let UnicodeDecodeError through.
    path = tmp_path / "board.toml"
    path.write_bytes(minimal_table.encode().replace(b"Motor angle", b"Motor \x98ngle"))
    refused(path, "not UTF-8 text", "byte ")


# ---------------------------------------------------------------------------
# [[emcy]], [[enum]], [[bitset]] and `values`: the minimal table plus one of each, carried by
# its fields (velocity_kp: 0..1 carries control_mode, motor_position: -10..10 the fault flags).
# ---------------------------------------------------------------------------
VALUE_SETS = """
[[emcy]]
name = "stale_sensor"
code = 0x5000
error_register = "generic"
description = "A sensor went stale"

[[emcy]]
name = "over_temperature"
code = 0x4210
error_register = "temperature"
description = "Too hot"

[[enum]]
name = "control_mode"
description = "Mode"

[[enum.values]]
name = "disabled"
value = 0
description = "Off"

[[enum.values]]
name = "velocity"
value = 1
description = "Velocity loop"

[[bitset]]
name = "fault_flags"
description = "Faults"

[[bitset.bits]]
name = "encoder_stale"
bit = 0
emcy = "stale_sensor"
about = "motor_position"
description = "No encoder sample"

[[bitset.bits]]
name = "over_temperature"
bit = 1
emcy = "over_temperature"
description = "The raiser names the object"
"""
CARRIERS = (
    ("default = 0.05", "default = 0.0  # disabled"),  # velocity_kp carries control_mode
    ('description = "Gain"', 'description = "Gain"\nvalues = "control_mode"'),
    ('description = "Motor angle"', 'description = "Motor angle"\nvalues = "fault_flags"'),
)


@pytest.fixture
def values_table(minimal_table: str) -> str:
    text = minimal_table + VALUE_SETS
    for old, new in CARRIERS:
        text = text.replace(old, new)
    return text


@pytest.fixture
def edit_values(values_table: str, write_table: TableWriter) -> TableEditor:
    """Replace one exact piece of the table with value sets, write it, return its path."""

    def edit(old: str, new: str) -> Path:
        assert values_table.count(old) == 1, f"test setup: {old!r} must occur exactly once"
        return write_table(values_table.replace(old, new))

    return edit


def test_value_sets_table_is_valid(values_table: str, write_table: TableWriter) -> None:
    table = load_table(write_table(values_table))
    # The table's own codes, then the standard ones it does not name.
    standard = [e["name"] for e in standard_document()["emcy"]]
    assert [e.name for e in table.emcy_codes] == [
        "stale_sensor",
        "over_temperature",
        *(name for name in standard if name not in ("stale_sensor", "over_temperature")),
    ]
    assert table.values_of("velocity_kp") == table.enum("control_mode")
    assert table.values_of("motor_position") == table.bitset("fault_flags")
    assert table.bitset("fault_flags").bit("over_temperature").about is None


def test_refuses_unknown_key_in_an_enum_value(edit_values: TableEditor) -> None:
    refused(
        edit_values("value = 1\n", "value = 1\nvalu = 2\n"),
        "enum 'control_mode': value 'velocity'",
        "unknown key 'valu'",
        "did you mean 'value'",
    )


def test_refuses_duplicate_enum_value(edit_values: TableEditor) -> None:
    refused(
        edit_values("value = 1\n", "value = 0\n"),
        "enum 'control_mode': value 'velocity'",
        "value 0 already used by 'disabled'",
    )


def test_refuses_duplicate_bit(edit_values: TableEditor) -> None:
    refused(
        edit_values("bit = 1\n", "bit = 0\n"),
        "bitset 'fault_flags': bit 'over_temperature'",
        "bit 0 already used by 'encoder_stale'",
    )


def test_refuses_bit_that_a_float_cannot_hold(edit_values: TableEditor) -> None:
    refused(
        edit_values("bit = 1\n", "bit = 24\n"),
        "bit 'over_temperature'",
        "bit 24 outside 0..23",
    )


def test_refuses_bit_naming_an_unknown_emcy(edit_values: TableEditor) -> None:
    refused(
        edit_values('emcy = "stale_sensor"', 'emcy = "stale_sensr"'),
        "bit 'encoder_stale'",
        "no [[emcy]] named 'stale_sensr'",
        "did you mean 'stale_sensor'",
    )


def test_refuses_about_without_emcy(edit_values: TableEditor) -> None:
    refused(
        edit_values('emcy = "stale_sensor"\n', ""),
        "bit 'encoder_stale'",
        "about names the object of an EMCY: set emcy too",
    )


def test_refuses_about_naming_an_unknown_field(edit_values: TableEditor) -> None:
    refused(
        edit_values('about = "motor_position"', 'about = "motor_postion"'),
        "bit 'encoder_stale'",
        "no board object named 'motor_postion'",
        "did you mean 'motor_position'",
    )


def test_refuses_values_naming_an_unknown_enum(edit_values: TableEditor) -> None:
    refused(
        edit_values('values = "control_mode"', 'values = "control_mod"'),
        "field 'velocity_kp'",
        "no enum or bitset named 'control_mod'",
        "did you mean 'control_mode'",
    )


def test_refuses_enum_value_outside_the_carrying_fields_range(edit_values: TableEditor) -> None:
    extra = '\n[[enum.values]]\nname = "torque"\nvalue = 2\ndescription = "Torque loop"\n'
    refused(
        edit_values('description = "Velocity loop"\n', f'description = "Velocity loop"\n{extra}'),
        "field 'velocity_kp'",
        "control_mode value 2 outside its range [0.0, 1.0]",
    )


def test_refuses_an_enum_carrier_whose_default_is_no_value(edit_values: TableEditor) -> None:
    refused(
        edit_values("default = 0.0  # disabled", "default = 0.5"),
        "field 'velocity_kp'",
        "default 0.5 is no control_mode value (disabled 0, velocity 1)",
    )


def test_refuses_bitset_whose_bits_exceed_the_carrying_fields_range(edit_values: TableEditor) -> None:
    refused(
        edit_values("bit = 1\n", "bit = 4\n"),
        "field 'motor_position'",
        "fault_flags value 17 outside its range [-10.0, 10.0]",
    )


def test_refuses_duplicate_emcy_code(edit_values: TableEditor) -> None:
    refused(
        edit_values("code = 0x4210", "code = 0x5000"),
        "emcy 'over_temperature'",
        "code 0x5000 already used",
    )


def test_refuses_unknown_error_register(edit_values: TableEditor) -> None:
    refused(
        edit_values('error_register = "temperature"', 'error_register = "temprature"'),
        "emcy 'over_temperature'",
        "unknown error_register 'temprature'",
        "one of: generic, current, voltage, temperature",
    )


PROFILE = """
[[pdo_profile]]
name = "turns"
description = "TPDO1 every 10th SYNC, from counter 3"
sync_counter_overflow = {overflow}

[[pdo_profile.tpdo]]
number = 1
transmission_type = 10
sync_start = 3
map = ["motor_duty"]
"""


def test_a_pdo_profile_maps_the_same_slots_and_full_is_the_default(
    minimal_table: str, write_table: TableWriter
) -> None:
    table = load_table(write_table(minimal_table + PROFILE.format(overflow=240)))
    assert [p.name for p in table.pdo_profiles] == ["full", "turns"]
    assert table.with_pdo_profile("full").tpdos == table.tpdos
    turns = table.with_pdo_profile("turns")
    assert [(p.enabled, p.transmission_type, p.sync_start) for p in turns.tpdos] == [
        (True, 10, 3),
        (False, 255, 0),
    ]
    assert not any(p.enabled for p in turns.rpdos), "a slot the profile does not list is disabled"
    assert turns.fields == table.fields
    with pytest.raises(KeyError, match="did you mean 'turns'"):
        table.pdo_profile("turn")


def test_refuses_a_sync_start_outside_a_profile_or_off_the_counter(
    minimal_table: str, write_table: TableWriter
) -> None:
    refused(
        write_table(minimal_table + PROFILE.format(overflow=25)),
        "turns",
        "sync_counter_overflow that type 10 divides",
    )
    refused(
        write_table(
            minimal_table.replace("transmission_type = 1\n", "transmission_type = 1\nsync_start = 1\n")
        ),
        "TPDO1: sync_start only in a [[pdo_profile]]",
    )
    refused(
        write_table(
            minimal_table
            + PROFILE.format(overflow=240).replace("transmission_type = 10", "transmission_type = 254")
        ),
        "sync_start needs a TPDO of transmission type 1..240",
    )
