"""The sequence ros2_canopen's `cia402_driver` puts a drive through, with the joint's physics
behind the firmware: init with homing (homing mode, shutdown, switch on, enable operation, homing
start, homing attained), mode switches in operation enabled (cyclic synchronous position with the
target at the actual position first, cyclic synchronous velocity, profile velocity), halt and
release, then recover from a fault (fault reset, then the enable sequence again, the mode kept).

Driven as that driver drives: raw controlwords in the master's RPDO, one transition at a time,
each confirmed by the statusword in the drive's TPDO; the mode by 0x6060 in the same RPDO,
confirmed by 0x6061. The master is python-canopen's `BaseNode402` used for its PDOs only
(tests/cia402_master.py says how it meets the lockstep rig).
"""

from __future__ import annotations

import numpy as np
import pytest
from cia402_master import HARD_STOP_RAD, HardStop, cia402_face, master, params_file, wait_for

from boardproto.cia402 import ControlBit, State, StatusBit, state_of
from hilrig.table import BOARD_TABLE

pytestmark = pytest.mark.bus

SHUTDOWN, SWITCH_ON, ENABLE_OPERATION, DISABLE_VOLTAGE = 0x06, 0x07, 0x0F, 0x00
HOMING_START = ENABLE_OPERATION | 1 << ControlBit.NEW_SET_POINT
HALT = ENABLE_OPERATION | 1 << ControlBit.HALT
FAULT_RESET = 1 << ControlBit.FAULT_RESET
HOMING_ATTAINED = 1 << StatusBit.OPERATION_MODE_SPECIFIC_12 | 1 << StatusBit.TARGET_REACHED
MODE = {mode.name: mode.value for mode in BOARD_TABLE.enum("cia402_mode").values}


def shown(node) -> State | None:
    return state_of(node.tpdo_values[0x6041])


def transition(node, controlword: int, state: State) -> None:
    """One controlword, then the statusword TPDO until it shows `state` (cia402_driver's way)."""
    node.controlword = controlword
    wait_for(lambda: shown(node) is state, f"{state.text} after controlword 0x{controlword:02X}")


def enable(node) -> None:
    for controlword, state in (
        (SHUTDOWN, State.READY_TO_SWITCH_ON),
        (SWITCH_ON, State.SWITCHED_ON),
        (ENABLE_OPERATION, State.OPERATION_ENABLED),
    ):
        transition(node, controlword, state)


def switch_mode(node, mode: str) -> None:
    """0x6060 in the master's RPDO beside the controlword (the profile maps them together)."""
    modes_of_operation = node.rpdo_pointers[0x6060]
    modes_of_operation.raw = MODE[mode]
    modes_of_operation.pdo_parent.transmit()
    wait_for(lambda: node.tpdo_values[0x6061] == MODE[mode], f"0x6061 shows {mode}")


@pytest.mark.requirement("CIA402_03")
@pytest.mark.no_approved_trace(
    "driven by a wall-clock master: how many lockstep cycles pass while it waits depends on the "
    "host, so the cycle of each command does too; the verdicts do not"
)
def test_ros2_canopen_sequence_init_with_homing_mode_switches_halt_and_recover(
    make_scenario, private_bus, hil_board, tmp_path
) -> None:
    s = make_scenario(before_start=cia402_face, trace=False, extra_args=params_file(tmp_path))
    s.rig.add_observer(HardStop(s.rig))
    with master(s, private_bus, hil_board.eds) as (node, stepper):
        node.setup_402_state_machine()
        wait_for(lambda: shown(node) is State.SWITCH_ON_DISABLED, "switch on disabled after boot")

        # Init: homing on the hard stop, in operation enabled.
        node.sdo["homing_method"].raw = -3
        switch_mode(node, "homing")
        enable(node)
        node.controlword = HOMING_START
        wait_for(lambda: node.tpdo_values[0x6041] & HOMING_ATTAINED == HOMING_ATTAINED, "homing attained")
        homed_at = s.rig.plant.state.motor_angle_rad / s.rig.plant.params.gear_ratio
        node.controlword = ENABLE_OPERATION

        # Mode switches in operation enabled, each target set before its mode.
        node.rpdo[3]["target_position"].raw = node.tpdo_values[0x6064]
        node.rpdo[3]["target_velocity"].raw = 0
        node.rpdo[3].transmit()
        switch_mode(node, "cyclic_synchronous_position")
        switch_mode(node, "cyclic_synchronous_velocity")
        node.rpdo[3]["target_velocity"].raw = 1000
        node.rpdo[3].transmit()
        switch_mode(node, "profile_velocity")
        wait_for(lambda: abs(node.tpdo_values[0x606C] - 1000) < 50, "1 rad/s in profile velocity")

        # Halt, then release: the drive stops in operation enabled and goes on.
        node.controlword = HALT
        wait_for(lambda: abs(node.tpdo_values[0x606C]) < 50, "at rest while halted")
        assert shown(node) is State.OPERATION_ENABLED, "halt keeps operation enabled"
        halted_from = s.rig.t
        stepper.cycles(200)
        halted_until = s.rig.t
        node.controlword = ENABLE_OPERATION
        wait_for(lambda: abs(node.tpdo_values[0x606C] - 1000) < 50, "1 rad/s once released")

        # Recover: a fault (the encoders go stale), then fault reset and the enable sequence.
        stepper.call(lambda: s.rig.pause_rpdo(1))
        wait_for(lambda: shown(node) is State.FAULT, "fault on stale encoders")
        stepper.call(lambda: s.rig.resume_rpdo(1))
        stepper.cycles(5)
        node.controlword = DISABLE_VOLTAGE  # fault reset acts on the bit's rising edge
        transition(node, FAULT_RESET, State.SWITCH_ON_DISABLED)
        enable(node)
        assert node.tpdo_values[0x6061] == MODE["profile_velocity"], "the mode outlives the fault"
        wait_for(lambda: abs(node.tpdo_values[0x606C] - 1000) < 50, "1 rad/s after recovery")
        transition(node, DISABLE_VOLTAGE, State.SWITCH_ON_DISABLED)

    assert homed_at == pytest.approx(HARD_STOP_RAD, abs=0.02), "homed where the hard stop is"
    _, words = s.rig.history("statusword")
    states = [state_of(int(word)) for word in words]
    order = [state for i, state in enumerate(states) if i == 0 or states[i - 1] is not state]
    fault = order.index(State.FAULT)
    assert order[fault - 2 : fault + 1] == [State.OPERATION_ENABLED, State.FAULT_REACTION_ACTIVE, State.FAULT]
    assert order[fault + 1 :] == [
        State.SWITCH_ON_DISABLED,
        State.READY_TO_SWITCH_ON,
        State.SWITCHED_ON,
        State.OPERATION_ENABLED,
        State.SWITCH_ON_DISABLED,
    ], "recovered through the enable sequence"
    t_velocity, velocity = s.rig.history("velocity_actual_value")
    halted = (t_velocity >= halted_from) & (t_velocity <= halted_until)
    assert halted.any() and np.max(np.abs(velocity[halted])) < 100, "no motion while halted (mrad/s)"
