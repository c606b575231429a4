"""boardproto.cia402: the statusword names the drive's state as masters read it, and the table's
402 objects carry the profile's types into the EDS."""

from __future__ import annotations

from pathlib import Path

import canopen
import pytest

from boardproto.cia402 import DEVICE_PROFILE, STATUSWORD_STATES, State, state_of
from boardproto.eds import generate_eds
from boardproto.loader import PROFILE_RANGE, load_table

TABLE = Path(__file__).resolve().parents[1] / "board.toml"


@pytest.mark.parametrize(
    ("statusword", "state"),
    [
        (0x0250, State.SWITCH_ON_DISABLED),
        (0x0231, State.READY_TO_SWITCH_ON),
        (0x0233, State.SWITCHED_ON),
        (0x1637, State.OPERATION_ENABLED),  # mode bits 10 and 12 do not change the state
        (0x0217, State.QUICK_STOP_ACTIVE),
        (0x020F, State.FAULT_REACTION_ACTIVE),
        (0x0208, State.FAULT),
        (0x0000, State.NOT_READY_TO_SWITCH_ON),
    ],
)
def test_a_statusword_shows_one_state(statusword: int, state: State) -> None:
    assert state_of(statusword) is state
    assert STATUSWORD_STATES.label(statusword) == state.text


def test_a_pattern_of_no_state_says_so() -> None:
    assert state_of(0x0001) is None
    assert STATUSWORD_STATES.label(0x0001) == "1 (no CiA 402 state)"


def test_the_joints_device_type_is_a_402_servo_drive() -> None:
    device_type = load_table(TABLE).node.device_type
    assert device_type & 0xFFFF == DEVICE_PROFILE and device_type >> 16 == 0x02  # servo drive


def test_canopen_types_every_402_object_of_the_eds(tmp_path: Path) -> None:
    table = load_table(TABLE)
    eds = tmp_path / "board.eds"
    eds.write_text(generate_eds(table))
    od = canopen.import_od(str(eds))
    profile = [f for f in table.fields if f.index in PROFILE_RANGE]
    assert {f.index for f in profile} >= {0x6040, 0x6041, 0x6060, 0x6061, 0x6064, 0x607A, 0x60FF, 0x6502}
    for field in profile:
        assert od.get_variable(field.index, field.subindex).data_type == int(field.data_type), field.name
    assert od[0x6040].data_type == canopen.objectdictionary.UNSIGNED16
    assert od[0x6060].data_type == canopen.objectdictionary.INTEGER8
    assert od[0x607A].data_type == canopen.objectdictionary.INTEGER32
