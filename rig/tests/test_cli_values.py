"""The command line speaks the names board.toml gives to values: `hilrig get/set/watch` show
'velocity (1)' and 'none (0)', and `set` takes a name as well as a number. Against the in-process
FakeJointNode on python-can's virtual bus."""

from __future__ import annotations

import pytest

from hilrig.cli import main
from hilrig.session.fake_node import FakeJointNode
from hilrig.table import ControlMode, FaultFlags, LedPattern, RigTable


def run(capsys: pytest.CaptureFixture[str], channel: str, *argv: str) -> tuple[int, list[list[str]], str]:
    code = main([*argv, "--interface", "virtual", "--channel", channel, "--sdo-timeout", "2"])
    out, err = capsys.readouterr()
    return code, [line.split() for line in out.splitlines()], err


@pytest.fixture
def channel(channel: str, fake: FakeJointNode) -> str:
    """A virtual bus channel with the booted fake joint node on it."""
    return channel


def test_set_takes_a_value_name_and_get_shows_it(capsys: pytest.CaptureFixture[str], channel: str) -> None:
    code, rows, err = run(capsys, channel, "set", "control_mode=torque")
    assert (code, err) == (0, ""), err
    assert rows == [["control_mode", "=", "torque", f"({int(ControlMode.TORQUE)})"]]
    code, rows, err = run(capsys, channel, "get", "control_mode", "fault_flags")
    assert (code, err) == (0, "")
    assert rows == [
        ["control_mode", "=", "torque", f"({int(ControlMode.TORQUE)})"],
        ["fault_flags", "=", "none", "(0)"],
    ]


def test_set_still_takes_the_number(capsys: pytest.CaptureFixture[str], channel: str) -> None:
    code, rows, _ = run(capsys, channel, "set", f"control_mode={int(ControlMode.VELOCITY)}")
    assert code == 0
    assert rows == [["control_mode", "=", "velocity", f"({int(ControlMode.VELOCITY)})"]]


def test_a_misspelt_value_name_is_a_usage_error_with_the_close_names(
    capsys: pytest.CaptureFixture[str], channel: str
) -> None:
    code, rows, err = run(capsys, channel, "set", "control_mode=velocty")
    assert (code, rows) == (2, [])
    assert err.count("\n") == 1 and "no control_mode value named 'velocty'; did you mean 'velocity'?" in err


def test_a_bitset_takes_bit_names_joined_by_a_bar(capsys: pytest.CaptureFixture[str]) -> None:
    from hilrig.cli.sdo import parse_named

    faults = RigTable.load().board.bitset("fault_flags")
    both = FaultFlags.MOTOR_ENCODER_STALE | FaultFlags.THERMISTOR_STALE
    assert parse_named("fault_flags", faults, "motor_encoder_stale|thermistor_stale") == both
    assert parse_named("fault_flags", faults, "none") == 0
    assert parse_named("fault_flags", faults, "5") is None  # a number: parsed as one


def test_watch_shows_the_led_pattern_by_name(capsys: pytest.CaptureFixture[str], channel: str) -> None:
    code, rows, err = run(
        capsys,
        channel,
        "watch",
        "--once",
        "--nmt-start",
        "--sync-period-ms",
        "5",
        "led_pattern",
        "motor_duty",
    )
    assert (code, err) == (0, "")
    by_name = {row[0]: row for row in rows[2:]}
    assert by_name["led_pattern"][1:3] == ["on", f"({int(LedPattern.ON)})"]  # the fake node's LED
    assert by_name["motor_duty"][1:3] == ["0", "0.01%"]  # a field without names: its number alone


def test_watch_and_monitor_name_a_402_drives_state_and_mode() -> None:
    import struct

    import can

    from boardproto.cia301 import sdo_request_cob_id, sdo_response_cob_id
    from hilrig.cli.common import load_dbc, value_names
    from hilrig.cli.record import FrameDecoder
    from hilrig.cli.watch import Board
    from hilrig.engine.rig import DEFAULT_EDS_PATH
    from hilrig.session.buslog import NodeDbc

    table = RigTable.load()
    operation_enabled = 0x0637  # the state's bits, voltage enabled, remote, target reached
    board = Board([table.entry("statusword"), table.entry("modes_of_operation_display")], value_names(table))
    board.store("statusword", operation_enabled, "TPDO2 (0x290)")
    board.store("modes_of_operation_display", 3, "TPDO2 (0x290)")
    assert [row[1] for row in board.rows()] == ["OPERATION ENABLED (1591)", "profile_velocity (3)"]
    board.store("statusword", 0x0001, "TPDO2 (0x290)")
    assert board.rows()[0][1].startswith("1 (no CiA 402 state)")

    # hilrig monitor: the same names in an SDO upload of either object.
    node = 0x10
    dbc = NodeDbc(load_dbc(DEFAULT_EDS_PATH.with_name("board.dbc")), table, node)
    decoder = FrameDecoder(dbc, table, node, set())
    texts = []
    for index, answer in ((0x6041, struct.pack("<H2x", operation_enabled)), (0x6061, struct.pack("<b3x", 3))):
        command = 0x4B if index == 0x6041 else 0x4F  # expedited upload of 2 bytes, of 1 byte
        request = struct.pack("<BHB4x", 0x40, index, 0)
        decoder.describe(
            can.Message(arbitration_id=sdo_request_cob_id(node), data=request, is_extended_id=False)
        )
        response = struct.pack("<BHB", command, index, 0) + answer
        texts.append(
            decoder.describe(
                can.Message(arbitration_id=sdo_response_cob_id(node), data=response, is_extended_id=False)
            )
        )
    assert "statusword=OPERATION ENABLED (1591)" in texts[0]
    assert "modes_of_operation_display=profile_velocity (3)" in texts[1]
