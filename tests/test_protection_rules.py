"""The joint's protection rules pinned to the cycle: each scenario sets its limits apart from
the defaults and from each other, so a bound moved by one, a limit read from the wrong field or a
rule a cycle late gives a different answer, and asserts what the actuator does on the cycles
before and after each event, not only that the event happened.

Cycle arithmetic of the lockstep bus: the frames the rig sends before SYNC n are what the
firmware's cycle n sees, and the TPDOs after SYNC n are cycle n's outputs. A frame stream paused
from cycle c0 on was last seen in cycle c0 - 1, and a rule "L cycles without" fires in cycle
c0 - 1 + L, in the same cycle on every output downstream of it (sensors, modules and actuators
run in that order inside one cycle).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import FULL_MAPPING_ON_THE_IDEAL_BUS

from boardproto.cia301 import (
    ERROR_BEHAVIOUR_INDEX,
    HEARTBEAT_CONSUMER_INDEX,
    MASTER_NODE_ID,
    ErrorBehaviour,
    NmtState,
    heartbeat_cob_id,
    heartbeat_consumer_entry,
)
from hilrig.plants import JointParams
from hilrig.table import ControlMode, EmcyCode, FaultFlags, LedPattern

pytestmark = [pytest.mark.bus, FULL_MAPPING_ON_THE_IDEAL_BUS]

ENCODER_STALE_CYCLES = 13
THERMISTOR_STALE_CYCLES = 29
WATCHDOG_CYCLES = 37
SENSOR_RPDO = 1  # motor and output encoder counts, thermistor ADC, motor current
SETPOINT_RPDO = 2  # velocity and torque setpoints: the stream the watchdog watches
ENCODERS_STALE = FaultFlags.MOTOR_ENCODER_STALE | FaultFlags.OUTPUT_ENCODER_STALE


def by_cycle(s, name: str) -> dict[int, float]:
    """A TPDO field's values by the cycle that sent them."""
    t, values = s.rig.history(name)
    return {round(time / s.rig.period_s): float(v) for time, v in zip(t, values, strict=True)}


def moving(s, setpoint: float = 2.0) -> None:
    s.rig.set("control_mode", ControlMode.VELOCITY)
    s.rig.set("velocity_setpoint", setpoint)
    s.rig.run(seconds=0.2)


@pytest.mark.requirement("PROT_01", "PROT_02")
def test_stale_encoders_then_thermistor_each_at_their_own_limit(make_scenario) -> None:
    s = make_scenario()
    s.rig.set("encoder_stale_cycles", ENCODER_STALE_CYCLES)
    s.rig.set("thermistor_stale_cycles", THERMISTOR_STALE_CYCLES)
    moving(s)
    silent_from = s.rig.cycle
    s.rig.pause_rpdo(SENSOR_RPDO)
    s.rig.run(cycles=THERMISTOR_STALE_CYCLES + 10)
    encoders_at = silent_from - 1 + ENCODER_STALE_CYCLES
    thermistor_at = silent_from - 1 + THERMISTOR_STALE_CYCLES
    flags, safe, duty = by_cycle(s, "fault_flags"), by_cycle(s, "safe_state"), by_cycle(s, "motor_duty")
    for n in range(silent_from - 5, s.rig.cycle):
        expected = FaultFlags(0)
        if n >= encoders_at:
            expected |= ENCODERS_STALE
        if n >= thermistor_at:
            expected |= FaultFlags.THERMISTOR_STALE
        assert FaultFlags(int(flags[n])) == expected, f"cycle {n} (sensors silent from {silent_from})"
        assert safe[n] == (1.0 if n >= encoders_at else 0.0), f"safe_state at cycle {n}"
        if n >= encoders_at:
            assert duty[n] == 0, f"motor_duty at cycle {n}, in the safe state"
    assert duty[encoders_at - 1] != 0, "the motor was driven up to the cycle before the safe state"
    assert EmcyCode.STALE_SENSOR in [record.code for record in s.rig.emcy]


@pytest.mark.requirement("PROT_03")
def test_watchdog_trips_on_its_cycle_and_cuts_the_drive_there(make_scenario) -> None:
    s = make_scenario()
    s.rig.set("watchdog_cycles", WATCHDOG_CYCLES)
    moving(s)
    stopped_from = s.rig.cycle
    s.rig.pause_rpdo(SETPOINT_RPDO)
    s.rig.run(cycles=WATCHDOG_CYCLES + 10)
    trips_at = stopped_from - 1 + WATCHDOG_CYCLES
    tripped, flags, duty, led = (
        by_cycle(s, "watchdog_tripped"),
        by_cycle(s, "fault_flags"),
        by_cycle(s, "motor_duty"),
        by_cycle(s, "led_pattern"),
    )
    for n in range(stopped_from - 5, s.rig.cycle):
        late = n >= trips_at
        # The status LED: on while the mode runs, fast blink from the safe state's own cycle.
        assert LedPattern(int(led[n])) == (LedPattern.FAST_BLINK if late else LedPattern.ON), (
            f"LED at cycle {n}"
        )
        assert tripped[n] == (1.0 if late else 0.0), (
            f"watchdog_tripped at cycle {n} (stream stopped {stopped_from})"
        )
        assert FaultFlags(int(flags[n])) == (FaultFlags.COMMAND_WATCHDOG if late else FaultFlags(0)), (
            f"cycle {n}"
        )
        if late:
            assert duty[n] == 0, f"motor_duty at cycle {n}, after the trip"
        else:
            assert duty[n] != 0, f"motor_duty at cycle {n}: the last setpoint still holds until the trip"
    assert EmcyCode.SETPOINT_STREAM_LOST in [record.code for record in s.rig.emcy]


@pytest.mark.requirement("PROT_07")
def test_only_a_fault_clear_of_one_clears_the_latch(make_scenario) -> None:
    # fault_clear takes 0..1: a write of 0.5 or of 0 is no clear, and the latch with its safe
    # state and zero duty holds through it; 1 clears it in the next cycle.
    s = make_scenario()
    s.rig.set("watchdog_cycles", WATCHDOG_CYCLES)
    moving(s)
    s.rig.pause_rpdo(SETPOINT_RPDO)
    s.rig.run(cycles=WATCHDOG_CYCLES + 5)
    s.rig.resume_rpdo(SETPOINT_RPDO)  # the cause is gone, the latch holds
    s.rig.run(cycles=10)
    for value in (0.5, 0.0):
        written_at = s.rig.cycle
        s.rig.set("fault_clear", value)
        s.rig.run(cycles=10)
        flags, safe, duty = by_cycle(s, "fault_flags"), by_cycle(s, "safe_state"), by_cycle(s, "motor_duty")
        for n in range(written_at, s.rig.cycle):
            assert (FaultFlags(int(flags[n])), safe[n], duty[n]) == (FaultFlags.COMMAND_WATCHDOG, 1.0, 0), (
                f"fault_clear = {value}: cycle {n}"
            )
    cleared_at = s.rig.cycle
    s.rig.set("fault_clear", 1.0)
    s.rig.run(cycles=10)
    flags, safe = by_cycle(s, "fault_flags"), by_cycle(s, "safe_state")
    assert (FaultFlags(int(flags[cleared_at])), safe[cleared_at]) == (FaultFlags(0), 0.0), "cleared at once"


@pytest.mark.requirement("CTRL_01")
def test_the_duty_is_limited_to_max_duty(make_scenario) -> None:
    # max_duty set below any duty the loop would settle at: a step far out of reach holds the
    # duty at exactly max_duty (thermal_derate is 1 at ambient), never past it. (The velocity
    # loop and the drive arbiter both limit to it: one of the two limits changed alone does not
    # show on the bus.)
    max_duty = 0.37
    s = make_scenario()
    s.rig.set("max_duty", max_duty)
    s.rig.set("control_mode", ControlMode.VELOCITY)
    s.rig.set("velocity_setpoint", 20.0)
    s.rig.run(seconds=0.3)
    _, command = s.rig.history("motor_duty_command")
    assert float(np.max(np.abs(command))) == pytest.approx(max_duty, rel=1e-6)
    assert float(np.mean(np.isclose(command, max_duty, rtol=1e-6))) > 0.9, "pinned at the limit"


@pytest.mark.requirement("PROT_04")
def test_a_disabled_drive_never_trips_the_watchdog(make_scenario) -> None:
    s = make_scenario()
    s.rig.set("watchdog_cycles", WATCHDOG_CYCLES)
    s.rig.set("control_mode", ControlMode.DISABLED)
    s.rig.pause_rpdo(SETPOINT_RPDO)
    s.rig.run(cycles=3 * WATCHDOG_CYCLES)
    s.expect.never("watchdog_tripped", lambda v: v != 0.0, "a trip with the drive disabled")
    s.expect.stays_within("motor_duty", 0, 0)
    assert set(by_cycle(s, "led_pattern").values()) == {float(LedPattern.SLOW_BLINK)}, "disabled: slow blink"


@pytest.mark.requirement("PROT_05")
def test_thermal_derate_follows_its_line_and_bounds_the_duty(make_scenario) -> None:
    # Warning 31 degC, limit 47 degC: a derate line whose slope (1/16 per degC) and offset no
    # neighbouring rule shares; max_duty 0.7 is not the default 0.95. The motor is asked for more
    # than it may get, so the duty command sits on the bound max_duty * derate while the winding
    # heats (a hot enclosure, a winding with a 0.8 s thermal time constant).
    warning_c, limit_c, max_duty = 31.0, 47.0, 0.7
    s = make_scenario(params=JointParams().with_thermal_time_constant(0.8))
    s.rig.set("thermal_warning_c", warning_c)
    s.rig.set("thermal_limit_c", limit_c)
    s.rig.set("thermal_hysteresis_c", 3.0)
    s.rig.set("max_duty", max_duty)
    s.rig.set("control_mode", ControlMode.VELOCITY)
    s.rig.set("velocity_setpoint", 40.0)  # more than the motor reaches: the bound binds
    s.rig.plant.set_ambient_temperature(60.0)
    s.rig.run_until(lambda rig: rig.field("safe_state") == 1.0, within_s=4.0, what="over-temperature cut-off")
    s.rig.run(cycles=30)  # the temperature and derate go out every 10th cycle
    temperature, derate = by_cycle(s, "winding_temperature"), by_cycle(s, "thermal_derate")
    command, wanted = by_cycle(s, "motor_duty_command"), by_cycle(s, "velocity_controller_output")
    inside = [n for n in temperature if warning_c < temperature[n] < limit_c]
    assert len(inside) >= 5, f"expected several samples between warning and limit, got {len(inside)}"
    cut = min(n for n, d in derate.items() if d == 0.0)
    for n, t_c in sorted(temperature.items()):
        line = float(np.clip((limit_c - t_c) / (limit_c - warning_c), 0.0, 1.0))
        expected = line if n < cut else 0.0
        assert derate[n] == pytest.approx(expected, abs=1e-5), f"derate at cycle {n}, winding {t_c:.3f} degC"
        bound = np.float32(max_duty) * np.float32(derate[n])
        assert command[n] == pytest.approx(float(np.clip(wanted[n], -bound, bound)), rel=1e-6, abs=1e-7), (
            f"duty command at cycle {n}: the controller's {wanted[n]:.4f} "
            f"within +-{max_duty} * {derate[n]:.4f}"
        )
    assert temperature[cut] >= limit_c and all(temperature[n] < limit_c for n in temperature if n < cut), (
        f"the cut-off at cycle {cut} ({temperature[cut]:.3f} degC) is the first sample "
        f"at or over {limit_c} degC"
    )
    bound_binds = [n for n in inside if abs(wanted[n]) > max_duty * derate[n]]
    assert len(bound_binds) >= 3, "expected the derated bound to bind while derating"
    assert all(by_cycle(s, "motor_duty")[n] == 0 for n in derate if n >= cut)


# The master's heartbeat, watched through 0x1016: a consumer time and a sending period that no
# other rule shares (the watchdog counts 37 cycles, the sensors 13 and 29), so a timer started a
# cycle late, or a loss judged on the period instead of the consumer time, shows.
MASTER_CONSUMER_MS = 23
MASTER_EVERY_CYCLES = 7
SPARE_RPDO = 4  # unused by default: mapped here, every RPDO slot and consumer entry is in use
SPARE_MAX_DUTY = 0.61


def watch_the_master(rig, behaviour: ErrorBehaviour = ErrorBehaviour.PRE_OPERATIONAL) -> None:
    """Before the rig reads the node's PDOs (pre-operational): the consumer entries watch the
    master's heartbeat (and three other nodes: every entry in use, so the node's receive filter
    must list them all); the node's error behaviour (0x1029:01) is `behaviour`."""
    rig.node.wait_until_alive(rig.boot_timeout_s)
    others = (MASTER_NODE_ID - 1, MASTER_NODE_ID - 2, MASTER_NODE_ID - 3)
    for sub, node_id in enumerate((MASTER_NODE_ID, *others), start=1):
        entry = heartbeat_consumer_entry(node_id, MASTER_CONSUMER_MS)
        rig.node.download(HEARTBEAT_CONSUMER_INDEX, sub, entry.to_bytes(4, "little"))
    rig.node.download(ERROR_BEHAVIOUR_INDEX, 1, bytes([behaviour]))


def watch_the_master_and_map_max_duty(rig) -> None:
    """`watch_the_master` with 0x1029 "no change" (the node stays operational), and the spare
    RPDO carries max_duty. Every RPDO is then in use too."""
    watch_the_master(rig, ErrorBehaviour.NO_CHANGE)
    spare = rig.node.remote.rpdo[SPARE_RPDO]
    spare.read()
    spare.clear()
    spare.add_variable("max_duty")
    spare.trans_type = 255
    spare.enabled = True
    spare.save()


@pytest.mark.requirement("PROT_08")
def test_the_master_heartbeat_beside_every_rpdo_is_heard_until_it_stops(make_scenario) -> None:
    s = make_scenario(before_start=watch_the_master_and_map_max_duty)
    assert s.rig.driver.rpdo_of("max_duty") == SPARE_RPDO, "the rig sends max_duty in the spare RPDO"
    master_heartbeat = heartbeat_cob_id(MASTER_NODE_ID)
    beating = {"on": True, "last": -1}

    def master(rig) -> None:
        if beating["on"] and rig.cycle % MASTER_EVERY_CYCLES == 0:
            rig.send_frame(master_heartbeat, bytes([NmtState.OPERATIONAL]))
            beating["last"] = rig.cycle  # the frame lands before this cycle's SYNC

    s.rig.before_each_cycle(master)
    s.rig.set("control_mode", ControlMode.VELOCITY)
    s.rig.set("velocity_setpoint", 40.0)  # more than the motor reaches: the duty sits on its bound
    s.rig.run(cycles=3 * MASTER_CONSUMER_MS)
    capped_from = s.rig.cycle
    s.rig.set("max_duty", SPARE_MAX_DUTY)  # through the spare RPDO, with the next cycle
    s.rig.run(cycles=3 * MASTER_CONSUMER_MS)
    beating["on"] = False
    last = beating["last"]
    s.rig.run(cycles=2 * MASTER_CONSUMER_MS)
    lost_at = last - 1 + MASTER_CONSUMER_MS * 1000 // s.rig.period_us

    default_max_duty = s.rig.table.field("max_duty").default
    command, duty = by_cycle(s, "motor_duty_command"), by_cycle(s, "motor_duty")
    flags, safe = by_cycle(s, "fault_flags"), by_cycle(s, "safe_state")
    for n in range(capped_from - 10, s.rig.cycle):
        lost = n >= lost_at
        assert FaultFlags(int(flags[n])) == (FaultFlags.MASTER_HEARTBEAT_LOST if lost else FaultFlags(0)), (
            f"fault_flags at cycle {n} (last master heartbeat in cycle {last})"
        )
        assert safe[n] == (1.0 if lost else 0.0), f"safe_state at cycle {n}"
        if lost:
            assert duty[n] == 0, f"motor_duty at cycle {n}, the master lost"
        else:
            bound = np.float32(SPARE_MAX_DUTY if n >= capped_from else default_max_duty)
            assert command[n] == pytest.approx(float(bound), rel=1e-6), (
                f"duty command at cycle {n}: on its bound, max_duty by the spare RPDO from {capped_from}"
            )
    lost = [record for record in s.rig.emcy if record.code == EmcyCode.HEARTBEAT_ERROR]
    assert [record.object_index for record in lost] == [HEARTBEAT_CONSUMER_INDEX], s.rig.emcy
    assert lost[0].data[2] == MASTER_NODE_ID, f"the EMCY names the lost node: {lost[0].data.hex()}"
    assert lost[0].cycle == lost_at, f"{lost[0]}: expected in cycle {lost_at}"
    assert s.rig.driver.operational, "0x1029 = 1: the node stays operational"


def lose_the_master_while_moving(s) -> str:
    """The master beats every MASTER_EVERY_CYCLES, the joint moves, then the beats stop: the
    EMCY comes in the consumer time's own cycle and the TPDOs end with it. The NMT state the
    node's heartbeat says afterwards."""
    master_heartbeat = heartbeat_cob_id(MASTER_NODE_ID)
    beating = {"on": True, "last": -1}

    def master(rig) -> None:
        if beating["on"] and rig.cycle % MASTER_EVERY_CYCLES == 0:
            rig.send_frame(master_heartbeat, bytes([NmtState.OPERATIONAL]))
            beating["last"] = rig.cycle

    s.rig.before_each_cycle(master)
    moving(s, setpoint=40.0)
    beating["on"] = False
    last = beating["last"]
    s.rig.run(cycles=2 * MASTER_CONSUMER_MS)
    lost_at = last - 1 + MASTER_CONSUMER_MS * 1000 // s.rig.period_us
    lost = [record for record in s.rig.emcy if record.code == EmcyCode.HEARTBEAT_ERROR]
    assert [record.cycle for record in lost] == [lost_at], s.rig.emcy
    duty = by_cycle(s, "motor_duty")
    assert duty[lost_at - 1] != 0 and max(duty) == lost_at - 1, "TPDOs stop with the event's cycle"
    assert not s.rig.driver.operational
    states = [s.rig.node.remote.nmt.wait_for_heartbeat(timeout=30) for _ in range(2)]
    return states[-1]


@pytest.mark.requirement("PROT_08")
def test_the_master_heartbeat_lost_enters_pre_operational_by_default(make_scenario) -> None:
    s = make_scenario(before_start=watch_the_master)
    assert s.rig.node.error_behaviour is ErrorBehaviour.PRE_OPERATIONAL
    assert lose_the_master_while_moving(s) == "PRE-OPERATIONAL"
    assert s.rig.node.read("motor_duty") == 0, "the latched fault holds the duty at 0"
    # Pre-operational, the node takes no RPDO: the encoders go stale too.
    assert FaultFlags.MASTER_HEARTBEAT_LOST in FaultFlags(int(s.rig.node.read("fault_flags")))


@pytest.mark.requirement("PROT_08")
def test_the_master_heartbeat_lost_with_error_behaviour_stopped_stops_the_node(make_scenario) -> None:
    # 0x1029:01 = 2: the same loss, its EMCY in its cycle, then the node stopped (no PDO, its
    # heartbeat says so), not pre-operational.
    s = make_scenario(before_start=lambda rig: watch_the_master(rig, ErrorBehaviour.STOPPED))
    assert s.rig.node.error_behaviour is ErrorBehaviour.STOPPED
    assert lose_the_master_while_moving(s) == "STOPPED"
