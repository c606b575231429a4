"""An event-driven TPDO (transmission type 255, CiA 301 7.2.2.2), as masters such as
CANopenNode and python-canopen configure status PDOs: the node sends it once when it starts, then
once on each change of what it carries, and never while nothing changes, however many SYNCs pass.

The status TPDO (safe_state, fault_flags) is turned event-driven before the rig reads the node's
mapping; the watchdog trip, then the latch clear give two known changes. The frames are counted
and compared whole: a TPDO that goes out every cycle, never, or once too few shows.
"""

from __future__ import annotations

import pytest
from conftest import FULL_MAPPING_ON_THE_IDEAL_BUS

from hilrig.table import ControlMode, FaultFlags

pytestmark = [pytest.mark.bus, FULL_MAPPING_ON_THE_IDEAL_BUS]

STATUS_TPDO = 6  # safe_state, fault_flags
WATCHDOG_CYCLES = 19
SETPOINT_RPDO = 2


def status_tpdo_on_change(rig) -> None:
    rig.node.wait_until_alive(rig.boot_timeout_s)
    status = rig.node.remote.tpdo[STATUS_TPDO]
    status.read()
    assert [v.name for v in status.map] == ["safe_state", "fault_flags"], "the default status TPDO"
    status.trans_type = 255
    status.inhibit_time = 0
    status.event_timer = 0
    status.save()


@pytest.mark.requirement("PDO_04")
def test_an_event_driven_tpdo_goes_out_once_per_change_and_never_in_between(make_scenario) -> None:
    s = make_scenario(before_start=status_tpdo_on_change)
    s.rig.set("watchdog_cycles", WATCHDOG_CYCLES)
    s.rig.set("control_mode", ControlMode.VELOCITY)
    s.rig.set("velocity_setpoint", 2.0)
    s.rig.run(cycles=5 * WATCHDOG_CYCLES)
    s.rig.pause_rpdo(SETPOINT_RPDO)  # the watchdog trips: safe state, its fault bit
    s.rig.run(cycles=3 * WATCHDOG_CYCLES)
    s.rig.resume_rpdo(SETPOINT_RPDO)
    s.rig.run(cycles=2 * WATCHDOG_CYCLES)  # latched: nothing changes
    s.rig.set("fault_clear", 1.0)
    s.rig.run(cycles=3 * WATCHDOG_CYCLES)

    _, safe = s.rig.history("safe_state")
    _, flags = s.rig.history("fault_flags")
    frames = [(float(a), FaultFlags(int(b))) for a, b in zip(safe, flags, strict=True)]
    assert frames == [
        (0.0, FaultFlags(0)),  # when the node started
        (1.0, FaultFlags.COMMAND_WATCHDOG),  # the trip
        (0.0, FaultFlags(0)),  # the clear
    ], f"the status TPDO's frames, in order, over {s.rig.cycle} cycles"
