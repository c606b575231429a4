"""Which bit rate a robot needs (`hilrig.apps.robot_bus`): its modules' frames scheduled on the
timed bus from the table's mapping, no firmware run."""

from __future__ import annotations

from hilrig.apps.robot_bus import robot_bitrate
from hilrig.table import BOARD_TABLE

ONE_MBIT = 1_000_000


def test_one_lean_module_fits_1_mbit_at_1_khz() -> None:
    answer = robot_bitrate(BOARD_TABLE, [1], 1000, profile="lean", bitrates=(500_000, ONE_MBIT))
    assert answer.needed == ONE_MBIT and answer.late[500_000] > 0, answer.line()


def test_the_16_module_robot_at_1_khz_needs_more_than_classic_can() -> None:
    # The robot's 16 modules at its 1 kHz, each with the lean mapping: every module's actuator
    # TPDO, sensor and setpoint RPDOs and position RPDO every cycle, far beyond 1000 bits.
    answer = robot_bitrate(
        BOARD_TABLE, range(1, 17), 1000, profile="lean", bitrates=(ONE_MBIT, 4_000_000, 8_000_000)
    )
    assert answer.late[ONE_MBIT] > 0 and answer.late[4_000_000] > 0, answer.line()
    assert answer.needed == 8_000_000, answer.line()
    print(f"\n{answer.line()}")
