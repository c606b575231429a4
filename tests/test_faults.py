"""Faults end to end: how the firmware latches, reports and clears them, what NMT stop does to the
control loop, and what the rig reports when the firmware process dies. Each test is a scenario
on its own private bus, in lockstep, seeded; times are simulation time."""

from __future__ import annotations

import re

import can
import pytest
from canopen.nmt import NmtError
from conftest import FULL_MAPPING_ON_THE_IDEAL_BUS, NODE_ID, REPO, stop_summary

from boardproto import load_table
from boardproto.cia301 import SYNC_COB_ID, NmtCommand, NmtState
from boardproto.table import ERROR_RESET_CODE
from hilrig.errors import FirmwareError
from hilrig.plants import JointParams
from hilrig.session.faults import FaultInjector, FaultPlan
from hilrig.table import ControlMode, EmcyCode, FaultFlags

pytestmark = [pytest.mark.bus, FULL_MAPPING_ON_THE_IDEAL_BUS]

TABLE = load_table(REPO / "protocol" / "board.toml")
VELOCITY_MODE = ControlMode.VELOCITY
GEAR_RATIO = JointParams().gear_ratio

EMCY_ERROR_RESET = ERROR_RESET_CODE
EMCY_COMMAND_WATCHDOG = EmcyCode.SETPOINT_STREAM_LOST
EMCY_OWNERSHIP_VIOLATION = EmcyCode.OWNERSHIP_VIOLATION
COMMAND_WATCHDOG_BIT = FaultFlags.COMMAND_WATCHDOG
OWNERSHIP_VIOLATION_BIT = FaultFlags.OWNERSHIP_VIOLATION
HEARTBEAT_S = TABLE.node.heartbeat_ms / 1000


def emcy_codes(rig, *, after_s: float = 0.0, before_s: float = float("inf")) -> list[int]:
    return [record.code for record in rig.emcy if after_s <= record.time_s < before_s]


def start_velocity_loop(s, setpoint: float = 2.0) -> None:
    s.rig.set("control_mode", VELOCITY_MODE)
    s.rig.set("velocity_setpoint", setpoint)


@pytest.mark.firmware_platforms("linux", "qemu-virt")
@pytest.mark.requirement("PROT_07")
def test_latched_fault_holds_until_fault_clear_then_error_reset(make_scenario) -> None:
    s = make_scenario()
    start_velocity_loop(s)
    s.rig.run(seconds=0.1)
    s.rig.pause_rpdo(2)  # the setpoint stream stops: the command watchdog trips
    s.rig.run_until(
        lambda rig: rig.field("safe_state") == 1.0, within_s=0.1, what="the watchdog's safe state"
    )
    s.rig.resume_rpdo(2)  # the cause is gone...
    resumed_at = s.rig.t
    s.rig.run(seconds=0.1)
    s.expect.eventually(
        "watchdog_tripped", lambda v: v == 0.0, "watchdog_tripped back to 0", after_s=resumed_at
    )
    # ...but the fault stays latched: safe state, motor off, bit 4 only, no error reset on the bus.
    s.expect.stays_within("safe_state", 1, 1, after_s=resumed_at)
    s.expect.stays_within("fault_flags", COMMAND_WATCHDOG_BIT, COMMAND_WATCHDOG_BIT, after_s=resumed_at)
    s.expect.stays_within("motor_duty", 0, 0, after_s=resumed_at + s.rig.period_s)
    assert EMCY_COMMAND_WATCHDOG in emcy_codes(s.rig), (
        f"expected {EMCY_COMMAND_WATCHDOG!r}, got {emcy_codes(s.rig)}"
    )
    assert EMCY_ERROR_RESET not in emcy_codes(s.rig, after_s=resumed_at), (
        f"expected no EMCY error reset while latched, got {emcy_codes(s.rig, after_s=resumed_at)}"
    )

    cleared_at = s.rig.t
    s.rig.set("fault_clear", 1.0)  # SDO, between cycles: the next cycle clears the latch
    s.rig.run(seconds=0.4)
    t_clear = s.expect.eventually("safe_state", lambda v: v == 0.0, "safe_state == 0", after_s=cleared_at)
    assert t_clear == pytest.approx(cleared_at, abs=s.rig.period_s / 2), (
        f"expected the latch cleared in the first cycle after fault_clear at {cleared_at:.3f} s, "
        f"got {t_clear:.3f} s; {s.expect.evidence}"
    )
    s.expect.stays_within("fault_flags", 0, 0, after_s=t_clear)
    s.expect.eventually("motor_duty", lambda v: v != 0, "the motor driven again", after_s=t_clear)
    s.expect.settles_within(
        "motor_velocity", target=2.0 * GEAR_RATIO, tolerance=0.05, by_s=t_clear + 0.35, after_s=t_clear
    )
    resets = [r for r in s.rig.emcy if r.code == EMCY_ERROR_RESET and r.time_s >= cleared_at]
    assert resets, f"expected an EMCY error reset (0x0000) after the clear, got {emcy_codes(s.rig)}"
    print(
        f"\nwatchdog latch: resumed at {resumed_at:.3f} s, still latched until fault_clear at "
        f"{cleared_at:.3f} s, cleared at {t_clear:.3f} s, error reset at {resets[0].time_s:.3f} s"
    )


ROGUE_CYCLE = 200
"""The firmware's cycle (1 = first SYNC) at which the injected rogue module writes."""
ROGUE_VALUE = 0.875  # BoardInfo::rogue_value in firmware/platform/linux/boards/joint/main.cpp


@pytest.mark.requirement("PROT_09")
def test_write_by_a_non_owner_is_refused_and_reported_by_emcy(make_scenario) -> None:
    s = make_scenario(extra_args=["--inject-rogue-write-at-cycle", str(ROGUE_CYCLE)])
    start_velocity_loop(s)
    s.rig.run(seconds=0.3)
    rogue_index = ROGUE_CYCLE - 1  # the rig counts cycles from 0
    rogue_t = rogue_index * s.rig.period_s
    target = TABLE.field("motor_duty_command")

    violations = [r for r in s.rig.emcy if r.code == EMCY_OWNERSHIP_VIOLATION]
    assert len(violations) == 1, f"expected one EMCY 0xFF00, got {[str(r) for r in s.rig.emcy]}"
    assert violations[0].object_index == target.index, str(violations[0])
    assert violations[0].cycle == rogue_index, str(violations[0])
    # The board kept the owner's value: in velocity mode the drive arbiter passes the velocity
    # controller's output through, and that is what the field holds in the rogue cycle too.
    t, duty_command = s.rig.history("motor_duty_command")
    _, controller = s.rig.history("velocity_controller_output")
    at = round(rogue_t / s.rig.period_s)
    assert t[at] == pytest.approx(rogue_t)
    assert duty_command[at] == controller[at] != ROGUE_VALUE, (
        f"expected motor_duty_command to keep its owner's {controller[at]:.4g} at t = {rogue_t:.3f} s "
        f"(cycle {rogue_index}), got {duty_command[at]:.4g}; {s.expect.evidence}"
    )
    s.expect.never("motor_duty_command", lambda v: v == ROGUE_VALUE, "the rogue value on the board")
    before = [r for r in s.rig.emcy if r.time_s < rogue_t]
    assert not before, f"expected no EMCY before the rogue write, got {[str(r) for r in before]}"
    t_latch = s.expect.eventually(
        "fault_flags",
        lambda v: int(v) & OWNERSHIP_VIOLATION_BIT,
        f"fault_flags {OWNERSHIP_VIOLATION_BIT!r}",
        after_s=rogue_t,
    )
    assert t_latch <= rogue_t + s.rig.period_s, (
        f"expected {OWNERSHIP_VIOLATION_BIT!r} latched by cycle {ROGUE_CYCLE}, at {t_latch}"
    )
    s.expect.stays_within("fault_flags", OWNERSHIP_VIOLATION_BIT, OWNERSHIP_VIOLATION_BIT, after_s=t_latch)
    s.expect.stays_within("safe_state", 1, 1, after_s=t_latch)
    s.expect.stays_within("motor_duty", 0, 0, after_s=t_latch + s.rig.period_s)
    s.close()
    counters = stop_summary(s.firmware)
    assert counters["board refused writes"] == 1, counters
    print(f"\nownership: {violations[0]}; firmware: {counters}")


@pytest.mark.requirement("NMT_02")
def test_nmt_stop_halts_pdos_and_cycles_and_start_resumes_them(make_scenario) -> None:
    s = make_scenario()
    start_velocity_loop(s)
    s.rig.run(seconds=0.1)
    stop_cycle = s.rig.cycle
    s.rig.nmt(NmtCommand.STOP)
    s.rig.run(seconds=0.05)  # the rig keeps sending SYNC (and its RPDOs): all ignored
    start_cycle = s.rig.cycle
    s.rig.nmt(NmtCommand.START)
    s.rig.run(seconds=0.35)
    stopped_cycles = start_cycle - stop_cycle

    period = s.rig.period_s
    for name in ("motor_duty", "motor_velocity", "safe_state"):
        t, _ = s.rig.history(name)
        cycles = [round(x / period) for x in t]
        expected = [*range(stop_cycle), *range(start_cycle, s.rig.cycle)]
        assert cycles == expected, (
            f"{name}: expected TPDOs in every cycle but {stop_cycle}..{start_cycle - 1} (stopped), "
            f"got {len(cycles)} cycles; {s.expect.evidence}"
        )
    # The loop kept working after the start: no fault (no control cycle ran while stopped, so
    # neither the watchdog nor the encoder staleness counted), and it tracks again.
    s.expect.never("fault_flags", lambda v: v != 0, "a fault")
    s.expect.settles_within(
        "motor_velocity", target=2.0 * GEAR_RATIO, tolerance=0.05, by_s=start_cycle * period + 0.3
    )
    s.close()
    counters = stop_summary(s.firmware)
    assert counters["cycles"] == s.rig.cycle - stopped_cycles, (
        f"expected {s.rig.cycle - stopped_cycles} control cycles ({s.rig.cycle} SYNCs, "
        f"{stopped_cycles} while stopped), got {counters}"
    )
    # The bus log agrees: between NMT stop and start, SYNCs and no TPDO.
    tpdo_ids = {p.cob_id for p in s.rig.node.tpdos.values() if p.enabled}
    between: list[can.Message] = []
    inside = False
    for message in can.LogReader(str(s.bus_log)):
        if message.arbitration_id == 0 and bytes(message.data) in (
            bytes([0x02, NODE_ID]),
            bytes([0x01, NODE_ID]),
        ):
            inside = message.data[0] == 0x02
        elif inside:
            between.append(message)
    syncs = sum(m.arbitration_id == SYNC_COB_ID for m in between)
    tpdos = [m for m in between if m.arbitration_id in tpdo_ids]
    assert syncs == stopped_cycles and not tpdos, (
        f"expected {stopped_cycles} SYNCs and no TPDO while stopped in {s.bus_log}, "
        f"got {syncs} SYNCs and {len(tpdos)} TPDOs"
    )
    print(
        f"\nNMT stop for {stopped_cycles} SYNCs: no TPDO, no cycle; firmware ran {counters['cycles']} cycles"
    )


KILL_CYCLE = 150


@pytest.mark.requirement("RIG_04")
def test_killed_firmware_is_named_at_its_cycle_and_its_heartbeat_is_missed(make_scenario) -> None:
    s = make_scenario()
    start_velocity_loop(s)
    s.rig.run(seconds=0.05)
    assert s.rig.node.heartbeat_age_s() is not None, "expected heartbeats before the kill"

    # The kill happens before cycle KILL_CYCLE's SYNC goes out (Firmware.kill waits for the exit).
    FaultInjector(
        s.rig, FaultPlan.parse([f"kill@{KILL_CYCLE * s.rig.period_s:g}"]), firmware=s.firmware
    ).install()
    with pytest.raises(FirmwareError) as raised:
        s.rig.run(seconds=0.3)
    message = str(raised.value)
    expected = rf"cycle {KILL_CYCLE} \(t = 0\.15 s\): joint-firmware .* killed by SIGKILL"
    assert re.match(expected, message), message
    assert s.rig.cycle == KILL_CYCLE

    # A heartbeat consumer (canopen's NMT master, and the rig's node layer) hears nothing for
    # three producer periods.
    with pytest.raises(NmtError):
        s.rig.node.remote.nmt.wait_for_heartbeat(timeout=3 * HEARTBEAT_S)
    age = s.rig.node.heartbeat_age_s()
    assert age is not None and age > 3 * HEARTBEAT_S, f"heartbeat age {age} s"
    assert s.rig.nmt_state is NmtState.OPERATIONAL  # the last one heard, before the kill

    s.close()  # the trace and bus log are complete now
    messages = list(can.LogReader(str(s.bus_log)))
    syncs = [m for m in messages if m.arbitration_id == SYNC_COB_ID]
    assert len(syncs) == KILL_CYCLE + 1, f"expected {KILL_CYCLE + 1} SYNCs in {s.bus_log}, got {len(syncs)}"
    import rerun as rr

    cycles: list[int] = []
    for chunk in rr.chunk.RrdReader(s.trace).stream():
        if chunk.entity_path == "/fields/virtual_sensors/motor_velocity" and not chunk.is_static:
            cycles += chunk.to_record_batch().to_pydict().get("cycle", [])
    assert sorted(cycles) == list(range(KILL_CYCLE)), (
        f"expected motor_velocity traced for cycles 0..{KILL_CYCLE - 1} in {s.trace}, "
        f"got {len(cycles)} samples up to {max(cycles, default=None)}"
    )
    print(f"\nkilled: {message.splitlines()[0]}; heartbeat age {age:.2f} s; {len(messages)} frames logged")
