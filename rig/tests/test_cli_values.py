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
