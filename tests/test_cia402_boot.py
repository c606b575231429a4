"""The node boots like a real device after an NMT reset: its boot-up comes the table's [node]
boot_ms later, counted in control cycles in lockstep, so a master written the usual way catches
it. python-canopen's `node.nmt.state = "RESET"` then `node.nmt.wait_for_bootup()` hears only
the frames that arrive after the wait began, and a boot-up sent right after the reset can beat
that call on a busy host. Here the stock idioms, unmodified, on `BaseNode402` (the master of
tests/cia402_master.py), and the rig's own reset, which runs exactly the boot's cycles.
"""

from __future__ import annotations

import itertools

import pytest
from cia402_master import WAIT_S, cia402_face, master, params_file, set_nmt_state
from conftest import FULL_MAPPING_ON_THE_IDEAL_BUS, TABLE

from boardproto.cia301 import NmtCommand
from boardproto.cia402 import State
from hilrig.table import ControlMode

pytestmark = pytest.mark.bus

WALL_CLOCK_MASTER = pytest.mark.no_approved_trace(
    "driven by a wall-clock master (BaseNode402): how many lockstep cycles pass while it waits "
    "depends on the host, so the cycle of each command does too; the verdicts do not"
)


def reset_and_wait(stepper, node, state: str) -> int:
    """The master's reset (between two cycles) and its stock wait for the boot-up; the rig's
    cycles from the reset to the moment the master had it."""
    rig = stepper.rig
    sent_at = [0]
    stepper.call(lambda: sent_at.__setitem__(0, rig.cycle))
    set_nmt_state(stepper, node, state)
    node.nmt.wait_for_bootup(WAIT_S)  # python-canopen's, stock: NmtError if it missed it
    return rig.cycle - sent_at[0]


@pytest.mark.requirement("NMT_03")
@WALL_CLOCK_MASTER
def test_python_canopens_reset_idioms_catch_the_boot_up(
    make_scenario, private_bus, hil_board, tmp_path
) -> None:
    s = make_scenario(before_start=cia402_face, trace=False, extra_args=params_file(tmp_path))
    boot_cycles = s.rig.boot_cycles
    assert boot_cycles >= 10, f"a boot time of tens of ms, got {boot_cycles} cycles"
    with master(s, private_bus, hil_board.eds) as (node, stepper):
        node.setup_402_state_machine()
        node.state = "OPERATION ENABLED"
        for state in ("RESET", "RESET COMMUNICATION"):
            cycles = reset_and_wait(stepper, node, state)
            # The boot-up went out with the SYNC of the boot's last cycle, not before.
            assert cycles >= boot_cycles - 1, f"{state}: boot-up after {cycles} cycles, boot {boot_cycles}"
            # Started again, the drive comes back under the same master (the profile's PDOs
            # are stored, so the reset kept them). At once: a lockstep node left pre-operational
            # gets no sensor frame, and its encoders go stale.
            set_nmt_state(stepper, node, "OPERATIONAL")
            node.check_statusword()  # a statusword TPDO sent after the start, not the cached one
            node.state = "OPERATION ENABLED"
            assert node.state == "OPERATION ENABLED", f"after {state}"
        node.state = "SWITCH ON DISABLED"
    _, words = s.rig.history("statusword")
    enabled = [int(w) & State.OPERATION_ENABLED.mask == State.OPERATION_ENABLED.value for w in words]
    assert sum(b and not a for a, b in itertools.pairwise(enabled)) >= 2, (
        "operation enabled left and entered again across the resets"
    )


@pytest.mark.requirement("NMT_03")
@WALL_CLOCK_MASTER
def test_store_reset_restore_reset_with_python_canopens_idioms(
    make_scenario, private_bus, hil_board, tmp_path
) -> None:
    s = make_scenario(before_start=cia402_face, trace=False, extra_args=params_file(tmp_path))
    default = TABLE.field("velocity_kp").default
    stored = default * 2.0
    with master(s, private_bus, hil_board.eds) as (node, stepper):
        node.sdo["velocity_kp"].raw = stored
        node.store()  # 0x1010:01 "save"
        reset_and_wait(stepper, node, "RESET")
        assert node.sdo["velocity_kp"].raw == pytest.approx(stored), "stored, then kept by the reset"
        node.restore()  # 0x1011:01 "load": the defaults apply at the next reset
        reset_and_wait(stepper, node, "RESET")
        assert node.sdo["velocity_kp"].raw == pytest.approx(default), "restored by the reset"
        # Restore all dropped the stored PDO profile too: the node stays pre-operational here.


@pytest.mark.requirement("NMT_03")
@FULL_MAPPING_ON_THE_IDEAL_BUS
def test_the_rigs_own_reset_runs_exactly_the_boot_cycles(make_scenario) -> None:
    s = make_scenario(trace=False)
    for command in (NmtCommand.RESET_NODE, NmtCommand.RESET_COMMUNICATION):
        s.rig.set("control_mode", ControlMode.VELOCITY)  # reset node: back at the defaults
        s.rig.set("velocity_setpoint", 2.0)
        s.rig.run(seconds=0.3)
        assert output_velocity(s) > 1.0, f"turning before {command.name}"
        before = s.rig.cycle
        s.rig.nmt(command)  # waits for the boot-up, running the node's boot meanwhile
        assert s.rig.cycle - before == s.rig.boot_cycles, f"{command.name}: the boot's cycles, no more"
        assert s.rig.boot_cycles >= 10, "a boot time of tens of ms"
        s.rig.nmt(NmtCommand.START)
    s.rig.set("control_mode", ControlMode.VELOCITY)
    s.rig.set("velocity_setpoint", 2.0)
    s.rig.run(seconds=0.3)
    s.expect.never("fault_flags", lambda v: v != 0, "a fault")
    assert output_velocity(s) > 1.0, "turning again after the resets"


def output_velocity(s) -> float:
    _, velocity = s.rig.history("output_velocity")
    return float(velocity[-1])
