"""PDO timing on the bus (CiA 301 7.2.2), set up as masters do before the rig reads the mapping:
a cyclic synchronous TPDO every N-th SYNC, an acyclic one only at a SYNC after a change, an
event-driven one no sooner than its inhibit time and again at its event timer with nothing
changed, and an RPDO's deadline (its event timer) raising EMCY 0x8250 until the next frame.

Each period is chosen apart from the others and from the defaults (7 SYNCs, 30 ms, 25 ms, 15 ms
against TPDO8's 10 SYNCs and the 50-cycle watchdog), so a timer that reads another's value, a
count off by one or a unit off by a factor shows as a wrong gap. The rig runs lockstep at 1 kHz:
one cycle is 1 ms of the firmware's control time, so a gap in cycles is the period in ms."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import FULL_MAPPING_ON_THE_IDEAL_BUS

from hilrig.table import ControlMode, EmcyCode, FaultFlags

pytestmark = [pytest.mark.bus, FULL_MAPPING_ON_THE_IDEAL_BUS]

CYCLIC_TPDO, EVERY_N_SYNCS = 5, 7  # torque_controller_output, output_position
DEFAULT_CYCLIC_TPDO, DEFAULT_N = 8, 10  # winding_temperature, thermal_derate (board.toml)
STATUS_TPDO = 6  # safe_state, fault_flags
VELOCITY_TPDO = 2  # motor_velocity, output_velocity
INHIBIT_MS, EVENT_TIMER_MS = 30, 25
SETPOINT_RPDO, DEADLINE_MS = 2, 15
WATCHDOG_CYCLES = 200  # longer than the deadline: the deadline's EMCY comes first


def cycles_of(rig, name: str) -> list[int]:
    """The cycles of the frames that carried `name`."""
    t, _ = rig.history(name)
    return np.rint(t / rig.period_s).astype(int).tolist()


def gaps(rig, name: str) -> list[int]:
    """The cycles between the frames that carried `name`."""
    return np.diff(cycles_of(rig, name)).tolist()


def synchronous_setup(rig) -> None:
    rig.node.wait_until_alive(rig.boot_timeout_s)
    cyclic = rig.node.remote.tpdo[CYCLIC_TPDO]
    cyclic.read()
    cyclic.trans_type = EVERY_N_SYNCS
    cyclic.save()
    status = rig.node.remote.tpdo[STATUS_TPDO]
    status.read()
    status.trans_type = 0  # acyclic synchronous
    status.save()


@pytest.mark.requirement("PDO_04")
def test_synchronous_tpdos_go_out_every_nth_sync_and_acyclic_ones_only_after_a_change(make_scenario) -> None:
    s = make_scenario(before_start=synchronous_setup)
    s.rig.set("watchdog_cycles", 20)
    s.rig.set("control_mode", ControlMode.VELOCITY)
    s.rig.set("velocity_setpoint", 2.0)
    s.rig.run(cycles=100)
    s.rig.pause_rpdo(SETPOINT_RPDO)  # the watchdog trips: safe state, its fault bit
    s.rig.run(cycles=60)
    s.rig.resume_rpdo(SETPOINT_RPDO)
    s.rig.set("fault_clear", 1.0)
    s.rig.run(cycles=100)

    assert set(gaps(s.rig, "output_position")) == {EVERY_N_SYNCS}, "type 7: every 7th SYNC"
    assert set(gaps(s.rig, "winding_temperature")) == {DEFAULT_N}, "board.toml's type 10: every 10th"
    _, safe = s.rig.history("safe_state")
    _, flags = s.rig.history("fault_flags")
    frames = [(float(a), FaultFlags(int(b))) for a, b in zip(safe, flags, strict=True)]
    assert frames == [
        (0.0, FaultFlags(0)),  # the first SYNC it is operational in
        (1.0, FaultFlags.COMMAND_WATCHDOG),  # the trip
        (0.0, FaultFlags(0)),  # the clear
    ], "type 0: at a SYNC, only when its values changed"
    trip, _ = cycles_of(s.rig, "safe_state")[1:]
    assert trip == 100 - 1 + 20, "the SYNC of the trip: 20 cycles after the last setpoint (cycle 99)"


def event_setup(rig) -> None:
    rig.node.wait_until_alive(rig.boot_timeout_s)
    velocity = rig.node.remote.tpdo[VELOCITY_TPDO]
    velocity.read()
    velocity.trans_type = 255
    velocity.inhibit_time = INHIBIT_MS * 10  # in 100 us
    velocity.event_timer = 0
    velocity.save()
    status = rig.node.remote.tpdo[STATUS_TPDO]
    status.read()
    status.trans_type = 255
    status.inhibit_time = 0
    status.event_timer = EVENT_TIMER_MS
    status.save()
    setpoints = rig.node.remote.rpdo[SETPOINT_RPDO]
    setpoints.read()
    setpoints.event_timer = DEADLINE_MS  # an RPDO's event timer: its reception deadline
    setpoints.save()


@pytest.mark.requirement("PDO_04")
def test_event_tpdo_timers_and_the_rpdo_deadline_keep_their_periods(make_scenario) -> None:
    s = make_scenario(before_start=event_setup)
    s.rig.set("watchdog_cycles", WATCHDOG_CYCLES)
    s.rig.set("control_mode", ControlMode.VELOCITY)
    s.rig.set("velocity_setpoint", 2.0)
    s.rig.run(cycles=300)
    paused_at = s.rig.cycle
    s.rig.pause_rpdo(SETPOINT_RPDO)
    s.rig.run(cycles=3 * DEADLINE_MS)
    resumed_at = s.rig.cycle
    s.rig.resume_rpdo(SETPOINT_RPDO)
    s.rig.run(cycles=20)

    # An event TPDO's first frame goes out when the node starts, before the rig's first cycle
    # (stamped 0, one cycle early): the gaps after it are the timers'. The velocity changes
    # every cycle while the joint accelerates and ripples: each frame goes out as soon as the
    # inhibit time since the last one has passed, never sooner.
    velocity_gaps = gaps(s.rig, "motor_velocity")[1:]
    assert set(velocity_gaps) == {INHIBIT_MS}, velocity_gaps
    # Nothing the status TPDO carries changes: it goes out at its event timer alone.
    assert set(gaps(s.rig, "safe_state")[1:]) == {EVENT_TIMER_MS}, "the event timer, unchanged values"

    timeouts = [e for e in s.rig.emcy if e.code == EmcyCode.RPDO_TIMEOUT]
    assert [e.data[:2] for e in timeouts] == [bytes([0x01, 0x14])], "one EMCY 0x8250 for 0x1401"
    # The last setpoint frame went out in cycle paused_at - 1, before that cycle's SYNC: the
    # node received it at the control time of cycle paused_at - 2, and 15 ms of it later the
    # deadline ends, in that cycle's SYNC.
    assert timeouts[0].cycle == paused_at - 2 + DEADLINE_MS, (timeouts[0].cycle, paused_at)
    resets = [e for e in s.rig.emcy if e.code == 0 and e.cycle >= resumed_at]
    assert resets and resets[0].cycle <= resumed_at + 1, "the next frame ends it (an error reset)"
    assert not FaultFlags(int(s.rig.field("fault_flags"))), "the watchdog never tripped"
