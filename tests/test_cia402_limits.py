"""The CiA 402 ARRAYs 0x607D (software position limit) and 0x6099 (homing speeds), set by name
over SDO like any field (each member is a sub-index of its array), acting on the joint's physics
in lockstep: a profile position target beyond the max limit stops at it, a cyclic synchronous
position target below the min limit stops there, and homing on the hard stop searches at
0x6099 sub 1's speed, not at the profile velocity. A sub-index past an array's count is
refused with "no such sub-index". The rig is the master here: the table's
"cia402" PDO profile carries the controlword and the targets in its RPDOs.
"""

from __future__ import annotations

import numpy as np
import pytest
from cia402_master import HARD_STOP_RAD, PROFILE, HardStop, params_file

from boardproto.cia301 import SdoAbortCode
from boardproto.cia402 import ControlBit, State, StatusBit, state_of
from hilrig.apps.pdo_profile import apply_pdo_profile
from hilrig.errors import SdoAbortError
from hilrig.table import BOARD_TABLE

pytestmark = pytest.mark.bus

SHUTDOWN, SWITCH_ON, ENABLE_OPERATION = 0x06, 0x07, 0x0F
NEW_SET_POINT = ENABLE_OPERATION | 1 << ControlBit.NEW_SET_POINT
MODE = {mode.name: mode.value for mode in BOARD_TABLE.enum("cia402_mode").values}
INTERNAL_LIMIT = 1 << StatusBit.INTERNAL_LIMIT_ACTIVE
HOMING_ATTAINED = 1 << StatusBit.OPERATION_MODE_SPECIFIC_12 | 1 << StatusBit.TARGET_REACHED


def cia402_pdos(rig) -> None:
    rig.node.wait_until_alive(rig.boot_timeout_s)
    apply_pdo_profile(rig.node, rig.table.board.pdo_profile(PROFILE))


def enable(rig, mode: str) -> None:
    rig.set("modes_of_operation", MODE[mode])
    for controlword in (SHUTDOWN, SWITCH_ON, ENABLE_OPERATION):
        rig.set("controlword", controlword)
        rig.run(cycles=5)
    assert state_of(int(rig.field("statusword"))) is State.OPERATION_ENABLED
    assert rig.field("modes_of_operation_display") == MODE[mode]


@pytest.mark.requirement("CIA402_05")
def test_position_targets_beyond_the_software_limits_stop_at_them(make_scenario, tmp_path) -> None:
    s = make_scenario(before_start=cia402_pdos, trace=False, extra_args=params_file(tmp_path))
    rig = s.rig
    assert (rig.read("min_position_limit"), rig.read("max_position_limit")) == (-10_000_000, 10_000_000)
    rig.set("max_position_limit", 300)  # 0x607D sub 2
    rig.set("min_position_limit", -200)  # 0x607D sub 1
    assert (rig.read("min_position_limit"), rig.read("max_position_limit")) == (-200, 300)
    limits = BOARD_TABLE.array_at(0x607D)
    assert limits is not None and rig.node.upload(limits.index, 0) == bytes([limits.count])
    with pytest.raises(SdoAbortError) as past:
        rig.node.upload(limits.index, limits.count + 1)
    assert past.value.abort_code == SdoAbortCode.SUB_INDEX_DOES_NOT_EXIST

    enable(rig, "profile_position")
    rig.set("target_position", 1000)
    rig.set("controlword", NEW_SET_POINT)
    rig.run(cycles=5)
    rig.set("controlword", ENABLE_OPERATION)
    rig.run(seconds=1.0)
    t, position = rig.history("position_actual_value")
    moved = t >= t[-1] - 1.0
    assert np.max(position[moved]) < 400, "stopped at the max limit (300 mrad), far short of 1000"
    assert abs(position[-1] - 300) <= rig.read("position_window"), "settled at the max limit"
    assert int(rig.field("statusword")) & INTERNAL_LIMIT, "statusword bit 11: the target was clamped"

    rig.set("modes_of_operation", MODE["cyclic_synchronous_position"])
    rig.set("target_position", -1000)
    rig.run(seconds=1.0)
    _, position = rig.history("position_actual_value")
    assert abs(position[-1] + 200) <= rig.read("position_window"), "settled at the min limit"
    assert np.min(position) > -300, "never near the -1000 asked for"
    assert int(rig.field("statusword")) & INTERNAL_LIMIT


@pytest.mark.requirement("CIA402_05")
def test_homing_on_the_hard_stop_searches_at_the_speed_for_the_switch(make_scenario, tmp_path) -> None:
    s = make_scenario(before_start=cia402_pdos, trace=False, extra_args=params_file(tmp_path))
    rig = s.rig
    rig.add_observer(HardStop(rig))
    rig.set("homing_method", -3)
    rig.set("speed_during_search_for_switch", 500)  # 0x6099 sub 1; profile_velocity stays 2000
    assert rig.read("speed_during_search_for_switch") == 500
    assert rig.read("profile_velocity") == 2000

    enable(rig, "homing")
    rig.set("controlword", NEW_SET_POINT)
    rig.run(seconds=1.0)
    assert int(rig.field("statusword")) & HOMING_ATTAINED == HOMING_ATTAINED, "homing attained"
    homed_at = rig.plant.state.motor_angle_rad / rig.plant.params.gear_ratio
    assert homed_at == pytest.approx(HARD_STOP_RAD, abs=0.02), "homed where the hard stop is"
    _, velocity = rig.history("velocity_actual_value")
    assert np.min(velocity) == pytest.approx(-500, abs=60), "searched at 0.5 rad/s, not at 2 rad/s"
