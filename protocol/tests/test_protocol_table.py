"""The real board.toml: the contract's names, kinds, HIL I/O and default PDOs."""

from __future__ import annotations

import pytest

from boardproto import Access, BoardTable, DataType, Kind, UnknownNameError
from boardproto.cia301 import FunctionCode, cob_id

CONTRACT_FIELDS = {
    Kind.SENSOR: [
        "motor_position",
        "output_position",
        "thermistor_resistance",
        "motor_current",
        "motor_encoder_raw",
        "output_encoder_raw",
        "heartbeat_lost",
    ],
    Kind.VIRTUAL_SENSOR: [
        "motor_velocity",
        "output_velocity",
        "spring_deflection",
        "joint_torque",
        "winding_temperature",
    ],
    Kind.MODULE: [
        "velocity_controller_output",
        "torque_controller_output",
        "motor_duty_command",
        "spring_constant_estimate",
        "spring_constant_confidence",
        "thermal_derate",
        "watchdog_tripped",
        "fault_flags",
        "safe_state",
        "led_pattern_command",
        # The CiA 402 drive face (firmware/joint/modules/Cia402Drive): what it hands the joint's
        # controllers, then the profile's read-only objects.
        "drive_mode",
        "drive_velocity_reference",
        "drive_torque_reference",
        "drive_position_reference",
        "drive_fault_reset",
        "drive_fault_ramp",
        "statusword",
        "modes_of_operation_display",
        "position_actual_value",
        "velocity_actual_value",
        "torque_actual_value",
        "supported_drive_modes",
    ],
    Kind.COMMAND: [
        "control_mode",
        "velocity_setpoint",
        "torque_setpoint",
        "position_setpoint",
        "fault_clear",
        "controlword",
        "modes_of_operation",
        "target_torque",
        "target_position",
        "target_velocity",
    ],
    Kind.PARAMETER: [
        "velocity_kp",
        "velocity_ki",
        "velocity_kd",
        "torque_kp",
        "torque_ki",
        "position_kp",
        "max_duty",
        "velocity_filter_hz",
        "spring_constant_nominal",
        "gear_ratio",
        "encoder_counts_per_rev",
        "output_encoder_counts_per_rev",
        "thermal_warning_c",
        "thermal_limit_c",
        "thermal_hysteresis_c",
        "watchdog_cycles",
        "encoder_stale_cycles",
        "ntc_r25_ohm",
        "ntc_beta_k",
        "motor_torque_constant",
        "thermistor_stale_cycles",
        "quick_stop_option_code",
        "fault_reaction_option_code",
        "following_error_window",
        "position_window",
        "velocity_window",
        "motor_rated_torque",
        "home_offset",
        "min_position_limit",
        "max_position_limit",
        "max_profile_velocity",
        "max_motor_speed",
        "profile_velocity",
        "profile_acceleration",
        "profile_deceleration",
        "quick_stop_deceleration",
        "homing_method",
        "speed_during_search_for_switch",
        "speed_during_search_for_zero",
    ],
}


@pytest.mark.parametrize("kind", list(CONTRACT_FIELDS))
def test_fields_of_each_kind_are_the_contracts(table: BoardTable, kind: Kind) -> None:
    assert [f.name for f in table.fields_of_kind(kind)] == CONTRACT_FIELDS[kind]


def test_only_commands_and_parameters_are_bus_writable(table: BoardTable) -> None:
    for field in table.fields:
        expected = Access.READ_WRITE if field.kind.bus_writable else Access.READ_ONLY
        assert field.access is expected, field.name
        assert field.stored == (field.kind is Kind.PARAMETER), field.name


@pytest.mark.parametrize(
    ("name", "default", "unit"),
    [
        ("velocity_kp", 0.1, "1/(rad/s)"),
        ("gear_ratio", 50.0, "1"),
        ("spring_constant_nominal", 50.0, "N*m/rad"),
        ("thermal_warning_c", 80.0, "degC"),
        ("thermal_limit_c", 100.0, "degC"),
        ("thermal_hysteresis_c", 10.0, "K"),
        ("watchdog_cycles", 50.0, "cycle"),
        ("encoder_stale_cycles", 20.0, "cycle"),
        ("max_duty", 0.95, "1"),
        ("encoder_counts_per_rev", 4096.0, "count"),
        ("output_encoder_counts_per_rev", 16384.0, "count"),
        ("ntc_r25_ohm", 10000.0, "ohm"),
        ("ntc_beta_k", 3950.0, "K"),
    ],
)
def test_parameter_defaults(table: BoardTable, name: str, default: float, unit: str) -> None:
    field = table.field(name)
    assert (field.default, field.unit) == (default, unit)


def test_hil_io_objects_have_hardware_types(table: BoardTable) -> None:
    inputs = {io.name: (io.index, io.data_type) for io in table.hil_inputs}
    outputs = {io.name: (io.index, io.data_type) for io in table.hil_outputs}
    assert inputs == {
        "motor_encoder_counts": (0x3000, DataType.UNSIGNED16),
        "output_encoder_counts": (0x3001, DataType.UNSIGNED16),
        "thermistor_adc": (0x3002, DataType.UNSIGNED16),
        "motor_current_adc": (0x3003, DataType.INTEGER16),
    }
    assert outputs == {
        "motor_duty": (0x3100, DataType.INTEGER16),
        "led_pattern": (0x3101, DataType.UNSIGNED8),
    }
    assert (table.hil_input("thermistor_adc").min, table.hil_input("thermistor_adc").max) == (
        0,
        4095,
    )
    assert table.hil_output("motor_duty").max == 10000


def test_default_rpdos_follow_the_contract(table: BoardTable) -> None:
    assert len(table.rpdos) == 4
    layout = [
        (p.cob_id(0x10), p.enabled, p.transmission_type, [e.name for e in p.entries]) for p in table.rpdos
    ]
    assert layout == [
        (
            cob_id(FunctionCode.RPDO1, 0x10),
            True,
            255,
            [
                "motor_encoder_counts",
                "output_encoder_counts",
                "thermistor_adc",
                "motor_current_adc",
            ],
        ),
        (cob_id(FunctionCode.RPDO2, 0x10), True, 255, ["velocity_setpoint", "torque_setpoint"]),
        (cob_id(FunctionCode.RPDO3, 0x10), True, 255, ["control_mode", "position_setpoint"]),
        (cob_id(FunctionCode.RPDO4, 0x10), False, 255, []),
    ]


def test_default_tpdos_follow_the_contract(table: BoardTable) -> None:
    assert len(table.tpdos) == 8
    tpdo1 = table.tpdo(1)
    assert (tpdo1.cob_id(0x10), tpdo1.transmission_type) == (cob_id(FunctionCode.TPDO1, 0x10), 1)
    assert [(e.name, e.bits) for e in tpdo1.entries] == [("motor_duty", 16), ("led_pattern", 8)]
    for pdo in table.tpdos[1:]:
        assert pdo.enabled
        assert pdo.transmission_type in (1, 10), pdo.name
        assert [e.bits for e in pdo.entries] == [32, 32], pdo.name
        assert all(e.name in table.field_names for e in pdo.entries)
    cob_ids = [p.cob_id(0x10) for p in table.pdos if p.enabled]
    assert len(cob_ids) == len(set(cob_ids))


def test_pdo_mapping_value_packs_index_subindex_and_length(table: BoardTable) -> None:
    assert table.tpdo(1).entries[0].mapping_value == 0x3100_0010
    assert table.tpdo(2).entries[0].mapping_value == 0x2100_0020


def test_lookup_by_name_and_index(table: BoardTable) -> None:
    velocity = table.field("motor_velocity")
    assert (velocity.index, velocity.unit, velocity.kind) == (0x2100, "rad/s", Kind.VIRTUAL_SENSOR)
    assert table.entry("motor_duty") is table.hil_output("motor_duty")
    assert table.entry_at(0x2100) is velocity


def test_typo_raises_key_error_listing_close_matches(table: BoardTable) -> None:
    with pytest.raises(KeyError) as caught:
        table.field("motor_velocty")
    assert isinstance(caught.value, UnknownNameError)
    assert str(caught.value).startswith("no board field named 'motor_velocty'; did you mean ")
    assert "'motor_velocity'" in str(caught.value)


def test_unknown_pdo_number_is_refused(table: BoardTable) -> None:
    with pytest.raises(UnknownNameError, match=r"no TPDO9: the node has TPDO1\.\.8"):
        table.tpdo(9)


def test_table_is_frozen(table: BoardTable) -> None:
    with pytest.raises(AttributeError):
        table.field("gear_ratio").default = 10.0  # type: ignore[misc]
