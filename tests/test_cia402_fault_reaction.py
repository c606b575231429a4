"""The CiA 402 fault reaction option (0x605E) on the joint's physics, in lockstep: the rig is the
master (the profile's controlword and target RPDOs every cycle, its SDO writes between two), a
joint turning at 1 rad/s in cyclic synchronous velocity, and a fault that leaves the sensors (the
joint's own setpoint stream stops: the command watchdog). With 2 the drive slows down on the
quick stop deceleration (0x6085), the duty following the ramp, then shows fault; with 0 the duty
is zero in the fault's own cycle. A value the drive does not offer is refused by the table's range.
"""

from __future__ import annotations

import math

import pytest
from cia402_master import PROFILE, params_file

from boardproto.cia301 import SdoAbortCode
from boardproto.cia402 import State, state_of
from hilrig.apps.pdo_profile import apply_pdo_profile
from hilrig.errors import SdoAbortError
from hilrig.table import ControlMode, FaultFlags

pytestmark = pytest.mark.bus

SETPOINT_RPDO = 4  # the profile's RPDO of the joint's own setpoint stream, which the watchdog watches
WATCHDOG_CYCLES = 50
QUICK_STOP_DECELERATION = 25000  # mrad/s^2: 25 mrad/s less a cycle of 1 ms (0x6084 is 20000)
TARGET_MRAD_S = 1000
SHUTDOWN, SWITCH_ON, ENABLE_OPERATION = 0x06, 0x07, 0x0F
CYCLIC_SYNCHRONOUS_VELOCITY = 9


def by_cycle(s, name: str) -> dict[int, float]:
    """A TPDO field's values by the cycle that sent them."""
    t, values = s.rig.history(name)
    return {round(time / s.rig.period_s): float(v) for time, v in zip(t, values, strict=True)}


def cia402_profile(rig) -> None:
    """The table's "cia402" PDO profile, every RPDO the rig's (the rig is the master here)."""
    rig.node.wait_until_alive(rig.boot_timeout_s)
    apply_pdo_profile(rig.node, rig.table.board.pdo_profile(PROFILE))


def turning(s, option: int) -> None:
    """Operation enabled in cyclic synchronous velocity at 1 rad/s, the watchdog watching."""
    s.rig.set("fault_reaction_option_code", option)
    s.rig.set("quick_stop_deceleration", QUICK_STOP_DECELERATION)
    s.rig.set("watchdog_cycles", WATCHDOG_CYCLES)
    s.rig.set("velocity_setpoint", 0.0)
    s.rig.set("control_mode", ControlMode.VELOCITY)  # the joint's own face: the watchdog runs
    s.rig.set("modes_of_operation", CYCLIC_SYNCHRONOUS_VELOCITY)
    s.rig.set("target_velocity", TARGET_MRAD_S)
    for name in ("target_torque", "target_position"):  # the other integer objects of the RPDOs
        s.rig.set(name, 0)
    for controlword in (SHUTDOWN, SWITCH_ON, ENABLE_OPERATION):
        s.rig.set("controlword", controlword)
        s.rig.run(cycles=3)
    s.rig.run(seconds=0.3)
    assert state_of(int(s.rig.field("statusword"))) is State.OPERATION_ENABLED
    assert abs(s.rig.field("velocity_actual_value") - TARGET_MRAD_S) < 50, "at 1 rad/s"


def fault_timeline(s) -> tuple[int, dict[int, State], dict[int, float], dict[int, float]]:
    """The setpoint stream stops; the cycle the watchdog latches, and the states, duty and
    velocity by cycle."""
    s.rig.pause_rpdo(SETPOINT_RPDO)
    s.rig.run(cycles=WATCHDOG_CYCLES + 150)
    flags = by_cycle(s, "fault_flags")
    latched = min(n for n, v in flags.items() if v != 0)
    assert FaultFlags(int(flags[latched])) == FaultFlags.COMMAND_WATCHDOG, "a fault that keeps the sensors"
    states = {n: state_of(int(v)) for n, v in by_cycle(s, "statusword").items()}
    return latched, states, by_cycle(s, "motor_duty"), by_cycle(s, "velocity_actual_value")


@pytest.mark.requirement("CIA402_04")
def test_option_2_ramps_to_rest_on_the_quick_stop_deceleration_then_faults(make_scenario, tmp_path) -> None:
    s = make_scenario(before_start=cia402_profile, extra_args=params_file(tmp_path))
    turning(s, option=2)
    latched, states, duty, velocity = fault_timeline(s)

    # The drive reads the latch a cycle late: the fault's own cycle still runs the mode.
    assert states[latched] is State.OPERATION_ENABLED
    assert duty[latched] != 0
    reaction = latched + 1
    faulted = min(n for n, state in states.items() if state is State.FAULT)
    assert all(states[n] is State.FAULT_REACTION_ACTIVE for n in range(reaction, faulted))
    # The demand starts at the joint's velocity (0x606C, in whole mrad/s here) and loses
    # 25 mrad/s a cycle, the first step in the reaction's first cycle: fault in the cycle it
    # reaches zero, whatever the joint does meanwhile (within the start's rounding).
    start = velocity[reaction]
    steps = math.ceil(start / (QUICK_STOP_DECELERATION * s.rig.period_s))
    assert steps - 2 <= faulted - reaction <= steps - 1, (
        f"fault reaction active for cycles {reaction}..{faulted - 1} from {start} mrad/s: {steps} steps"
    )
    assert all(duty[n] > 0 for n in range(reaction, faulted)), (
        "the duty follows the ramp, not the safe state's zero"
    )
    assert duty[faulted - 1] < duty[reaction] / 2, "the duty ramped down"
    assert velocity[faulted] < start / 2, "the joint slowed down with it"
    assert all(duty[n] == 0 for n in duty if n >= faulted), "fault: the drive function disabled"
    assert all(states[n] is State.FAULT for n in states if n >= faulted)

    with pytest.raises(SdoAbortError) as refused:
        s.rig.set("fault_reaction_option_code", 3)
    assert refused.value.abort_code == SdoAbortCode.VALUE_TOO_HIGH


@pytest.mark.requirement("CIA402_04")
def test_option_0_zeroes_the_duty_in_the_faults_cycle(make_scenario, tmp_path) -> None:
    s = make_scenario(before_start=cia402_profile, extra_args=params_file(tmp_path))
    turning(s, option=0)
    latched, states, duty, _ = fault_timeline(s)

    assert duty[latched - 1] != 0
    assert all(duty[n] == 0 for n in duty if n >= latched), "zero duty from the fault's own cycle on"
    assert states[latched + 1] is State.FAULT_REACTION_ACTIVE
    assert all(states[n] is State.FAULT for n in states if n >= latched + 2)
