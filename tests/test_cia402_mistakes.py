"""Mistakes CiA 402 masters make, answered as the drive profile says, with `BaseNode402` as the
master (tests/cia402_master.py): a controlword that jumps over states, a mode 0x6502 does not
offer, a target written before operation enabled, a mode switch with the halt bit set.
"""

from __future__ import annotations

import canopen
import numpy as np
import pytest
from cia402_master import cia402_face, master, params_file, wait_for

from boardproto.cia301 import SdoAbortCode
from boardproto.cia402 import ControlBit

pytestmark = pytest.mark.bus

HALT = 1 << ControlBit.HALT
ENABLE_OPERATION = 0x0F


def still(rig, since_t: float, until_t: float) -> float:
    """The largest gearbox-side speed (mrad/s) of the plant between two simulation times."""
    t, motor_rad_s = rig.truth("motor_velocity_rad_s")
    window = (t >= since_t) & (t <= until_t)
    assert window.any(), "cycles in the window"
    return float(np.max(np.abs(motor_rad_s[window]))) / rig.plant.params.gear_ratio * 1000.0


@pytest.mark.requirement("CIA402_02")
@pytest.mark.no_approved_trace(
    "driven by a wall-clock master (BaseNode402): how many lockstep cycles pass while it waits "
    "depends on the host, so the cycle of each command does too; the verdicts do not"
)
def test_mistakes_of_masters_get_the_standard_reaction(
    make_scenario, private_bus, hil_board, tmp_path
) -> None:
    s = make_scenario(before_start=cia402_face, trace=False, extra_args=params_file(tmp_path))
    with master(s, private_bus, hil_board.eds) as (node, stepper):
        node.setup_402_state_machine()

        # A jump: enable operation straight from switch on disabled is no command there.
        node.controlword = ENABLE_OPERATION
        stepper.cycles(20)
        assert node.state == "SWITCH ON DISABLED"

        # A mode the drive does not offer: BaseNode402 checks 0x6502; written anyway, not taken.
        with pytest.raises(TypeError):
            node.op_mode = "VELOCITY"
        node.op_mode = "CYCLIC SYNCHRONOUS VELOCITY"
        node.sdo["modes_of_operation"].raw = 2
        stepper.cycles(20)
        assert node.op_mode == "CYCLIC SYNCHRONOUS VELOCITY", "0x6061 keeps the mode"
        with pytest.raises(canopen.SdoAbortedError) as refused:
            node.sdo["modes_of_operation"].raw = 11
        assert refused.value.code == SdoAbortCode.VALUE_TOO_HIGH

        # A target before operation enabled: nothing moves until enabled.
        node.state = "SWITCHED ON"
        node.rpdo[3]["target_velocity"].raw = 1000
        node.rpdo[3].transmit()
        before = s.rig.t
        stepper.cycles(200)
        disabled_until = s.rig.t
        node.state = "OPERATION ENABLED"
        wait_for(lambda: abs(node.tpdo_values[0x606C] - 1000) < 50, "1 rad/s once enabled")

        # A mode switch with halt set: the mode switches, the new mode stays halted.
        node.controlword = ENABLE_OPERATION | HALT
        node.op_mode = "PROFILED VELOCITY"
        wait_for(lambda: abs(node.tpdo_values[0x606C]) < 50, "halted")
        halted_from = s.rig.t
        stepper.cycles(300)
        halted_until = s.rig.t
        node.controlword = ENABLE_OPERATION
        wait_for(lambda: abs(node.tpdo_values[0x606C] - 1000) < 50, "1 rad/s once halt clears")
        node.state = "SWITCH ON DISABLED"

    assert still(s.rig, before, disabled_until) < 20, "no motion before operation enabled"
    # Halted at the target's 1 rad/s: the series spring rings out near rest, far from the target.
    assert still(s.rig, halted_from + 0.1, halted_until) < 100, "no motion while halted"
