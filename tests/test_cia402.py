"""The joint's CiA 402 drive face driven by a real master: python-canopen's `BaseNode402`,
unmodified, its waits stretched for a loaded host (tests/cia402_master.py says how it meets the
lockstep rig), the joint's physics behind the firmware: every state, every mode, homing on a hard
stop, a quick stop and a fault it recovers from.
"""

from __future__ import annotations

import logging

import numpy as np
import pytest
from cia402_master import (
    HARD_STOP_RAD,
    HardStop,
    State,
    cia402_face,
    master,
    params_file,
    states_seen,
    wait_for,
)

pytestmark = pytest.mark.bus


@pytest.mark.requirement("CIA402_01")
@pytest.mark.no_approved_trace(
    "driven by a wall-clock master (BaseNode402): how many lockstep cycles pass while it waits "
    "depends on the host, so the cycle of each command does too; the verdicts do not"
)
def test_base_node_402_drives_every_state_and_mode_homes_and_recovers(
    make_scenario, private_bus, hil_board, tmp_path, caplog
) -> None:
    s = make_scenario(before_start=cia402_face, trace=False, extra_args=params_file(tmp_path))
    s.rig.add_observer(HardStop(s.rig))
    caplog.set_level(logging.WARNING, logger="canopen")
    with master(s, private_bus, hil_board.eds) as (node, stepper):
        node.setup_402_state_machine()
        assert not [r for r in caplog.records if "not configured" in r.getMessage()], "402 objects in PDOs"
        assert node.is_op_mode_supported("CYCLIC SYNCHRONOUS TORQUE")
        assert not node.is_op_mode_supported("VELOCITY")

        # Homing on the hard stop: the drive moves negative until the joint stops following.
        node.sdo["homing_method"].raw = -3
        node.state = "SWITCH ON DISABLED"
        assert node.homing(), "BaseNode402.homing() on the hard stop"
        homed_at = s.rig.plant.state.motor_angle_rad / s.rig.plant.params.gear_ratio
        assert abs(node.sdo["position_actual_value"].raw) <= 5, "home is 0 mrad (home_offset 0)"

        for mode in (
            "PROFILED VELOCITY",
            "PROFILED TORQUE",
            "CYCLIC SYNCHRONOUS POSITION",
            "CYCLIC SYNCHRONOUS VELOCITY",
            "CYCLIC SYNCHRONOUS TORQUE",
            "PROFILED POSITION",
            "HOMING",
        ):
            node.op_mode = mode
            assert node.op_mode == mode

        # Profile velocity away from the stop at 1 rad/s, then a quick stop, then back.
        node.op_mode = "PROFILED VELOCITY"
        node.rpdo[3]["target_velocity"].raw = 1000
        node.rpdo[3].transmit()
        node.state = "OPERATION ENABLED"
        wait_for(lambda: abs(node.tpdo_values[0x606C] - 1000) < 50, "1 rad/s")
        # Quick stop option 6: ramp to rest on the quick stop deceleration and stay, so the
        # master sees quick stop active (BaseNode402 waits for it) and enables operation again.
        node.sdo["quick_stop_option_code"].raw = 6
        node.state = "QUICK STOP ACTIVE"
        wait_for(lambda: abs(node.tpdo_values[0x606C]) < 50, "at rest in quick stop active")
        node.state = "OPERATION ENABLED"
        wait_for(lambda: abs(node.tpdo_values[0x606C] - 1000) < 50, "1 rad/s again")

        # A fault: the sensor frame stops, the encoders go stale; the master resets it.
        stepper.call(lambda: s.rig.pause_rpdo(1))
        wait_for(lambda: node.state == "FAULT", "fault on stale encoders")
        stepper.call(lambda: s.rig.resume_rpdo(1))
        stepper.cycles(5)
        node.reset_from_fault()
        assert node.state == "OPERATION ENABLED"
        node.state = "SWITCH ON DISABLED"

    seen = states_seen(s.rig)
    for state in State:
        if state is not State.NOT_READY_TO_SWITCH_ON:  # left in the node's first cycle
            assert state.text in seen, f"{state.text} never shown: {seen}"
    assert homed_at == pytest.approx(HARD_STOP_RAD, abs=0.02), "homed where the hard stop is"
    _, velocity = s.rig.history("velocity_actual_value")
    assert np.max(velocity) > 950, "the joint turned at 1 rad/s in profile velocity"
