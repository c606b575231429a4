"""The CiA 402 drive profile's rules both languages need: the states of the drive's state
machine and the statusword bits that show them, the controlword bits, the other statusword bits.
The firmware gets them as `board/cia402.hpp`; the rig (`hilrig watch`, `monitor`) names a
drive's state with `state_of`. The objects themselves (0x6040, 0x6041...) are board fields of
the table."""

from __future__ import annotations

import enum


class State(enum.IntEnum):
    """The states of CiA 402's drive state machine; the value is the statusword's pattern."""

    NOT_READY_TO_SWITCH_ON = 0x00
    SWITCH_ON_DISABLED = 0x40
    READY_TO_SWITCH_ON = 0x21
    SWITCHED_ON = 0x23
    OPERATION_ENABLED = 0x27
    QUICK_STOP_ACTIVE = 0x07
    FAULT_REACTION_ACTIVE = 0x0F
    FAULT = 0x08

    @property
    def mask(self) -> int:
        """The statusword bits that tell this state (CiA 402, table of the statusword)."""
        return _MASKS[self]

    @property
    def text(self) -> str:
        """As masters print it: 'SWITCH ON DISABLED'."""
        return self.name.replace("_", " ")


# Bits 0..3 and 6 tell every state; bit 5 (quick stop) also tells the states where it can be 0.
_MASKS = {
    State.NOT_READY_TO_SWITCH_ON: 0x4F,
    State.SWITCH_ON_DISABLED: 0x4F,
    State.READY_TO_SWITCH_ON: 0x6F,
    State.SWITCHED_ON: 0x6F,
    State.OPERATION_ENABLED: 0x6F,
    State.QUICK_STOP_ACTIVE: 0x6F,
    State.FAULT_REACTION_ACTIVE: 0x4F,
    State.FAULT: 0x4F,
}


class ControlBit(enum.IntEnum):
    """Controlword (0x6040) bit numbers."""

    SWITCH_ON = 0
    ENABLE_VOLTAGE = 1
    QUICK_STOP = 2  # 0 commands the quick stop
    ENABLE_OPERATION = 3
    NEW_SET_POINT = 4  # profile position; homing: start
    CHANGE_SET_IMMEDIATELY = 5
    RELATIVE = 6
    FAULT_RESET = 7  # on its rising edge
    HALT = 8


class StatusBit(enum.IntEnum):
    """Statusword (0x6041) bit numbers besides the state's."""

    VOLTAGE_ENABLED = 4
    WARNING = 7
    REMOTE = 9
    TARGET_REACHED = 10
    INTERNAL_LIMIT_ACTIVE = 11
    OPERATION_MODE_SPECIFIC_12 = 12  # set-point acknowledge, speed zero, homing attained
    OPERATION_MODE_SPECIFIC_13 = 13  # following error, homing error


def state_of(statusword: int) -> State | None:
    """The state a statusword shows, None for a pattern of no state."""
    for state in State:
        if statusword & state.mask == state.value:
            return state
    return None


STATUSWORD_INDEX = 0x6041

DEVICE_PROFILE = 402
"""CiA 402's number: a drive's device type (0x1000) has it in its lower 16 bits, the drive's
kind in bits 16..23 (2: servo drive)."""


class StatuswordStates:
    """Names a statusword by the state it shows, as `ValueEnum.label` names an enum's value:
    'OPERATION ENABLED' for 0x0627 (what `hilrig watch` and `monitor` print)."""

    name = "cia402_state"

    def label(self, number: float) -> str:
        state = state_of(int(number))
        return state.text if state is not None else f"{number:g} (no CiA 402 state)"


STATUSWORD_STATES = StatuswordStates()
