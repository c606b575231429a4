"""The robot head module, the second board (protocol/boards/head.toml, build/bin/head-firmware,
hilrig.plants.head): its firmware on its own private bus against its plant, in lockstep, seeded.
The LED follows its commands, the rail trips on over-current and reports it, a battery that sags
under load latches low battery with its EMCY, and a rig built for the joint refuses the head.
Times are simulation time."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import HEAD_MAPPING_ON_THE_IDEAL_BUS

from hilrig import resources
from hilrig.errors import NodeSilentError
from hilrig.plants.head import HeadParams, HeadPlant
from hilrig.pytest_plugin.board import HilBoard
from hilrig.pytest_plugin.fixtures import BOOT_TIMEOUT_S, SCENARIO_SDO_TIMEOUT_S
from hilrig.session.builder import hil_session
from hilrig.session.run import FirmwareRun, RigRun, RunDescription, TraceRun
from hilrig.table import BOARD_TABLE, RigTable

pytestmark = [pytest.mark.bus, HEAD_MAPPING_ON_THE_IDEAL_BUS]

HEAD = RigTable.load(resources.HEAD_TABLE)
HeadFaults = HEAD.board.bitset("fault_flags").python_type()
HEAD_EMCY = {code.name: code.code for code in HEAD.board.emcy_codes}
ERROR_RESET = 0


def head_params(**values: float) -> HeadParams:
    return HeadParams.from_table(HEAD.board, **values)


def head_plant(params: HeadParams | None, seed: int) -> HeadPlant:
    """The plant factory (`RigRun.plant`): `make_scenario(params=head_params(...))`."""
    return HeadPlant(params if params is not None else head_params(), seed)


@pytest.fixture
def hil_board() -> HilBoard:
    """This module's board is the head (hilrig's pytest plugin: a project's own board, here the
    repository's second one): its table, EDS, firmware, plant and dashboard."""
    return HilBoard(
        table=HEAD,
        eds=resources.board_files(resources.HEAD_TABLE).eds,
        firmware=resources.HEAD_FIRMWARE,
        plant=head_plant,
        dashboard="head",
    )


def emcy_of(rig, name: str) -> list:
    return [record for record in rig.emcy if record.code == HEAD_EMCY[name]]


def test_leds_follow_their_commands_and_the_imu_sees_the_nod(make_scenario) -> None:
    s = make_scenario(params=head_params(nod_amplitude_rad=0.2, nod_hz=1.0))
    s.rig.set("led_red", 1.0)
    s.rig.set("led_blue", 0.25)
    s.rig.run(seconds=0.3)
    _, red = s.rig.history("led_red_pwm")
    _, green = s.rig.history("led_green_pwm")
    _, blue = s.rig.history("led_blue_pwm")
    pwm = (red[-1], green[-1], blue[-1])
    assert pwm == (255, 0, 64), f"expected LED PWM (255, 0, 64), got {pwm}; {s.expect.evidence}"
    _, true_red = s.rig.truth("led_red_duty")
    assert true_red[-1] == 1.0
    # The firmware's attitude from gravity against the plant's pitch, cycle by cycle.
    _, pitch = s.rig.history("head_pitch")
    _, true_pitch = s.rig.truth("pitch_rad")
    worst = float(np.max(np.abs(pitch[5:] - true_pitch[5 : len(pitch)])))
    assert worst < 0.01, f"expected |head_pitch - pitch| < 0.01 rad, got {worst:.4f}; {s.expect.evidence}"


def test_rail_over_current_trips_reports_and_clears(make_scenario) -> None:
    s = make_scenario()
    s.rig.run(seconds=0.05)
    s.rig.plant.set_extra_load(2.0)  # 2.6 A on a rail limited to 2 A
    shorted_at = s.rig.cycle
    s.rig.run(seconds=0.05)
    trips = emcy_of(s.rig, "rail_over_current")
    assert len(trips) == 1, f"expected one EMCY rail_over_current, got {[str(r) for r in s.rig.emcy]}"
    assert trips[0].object_index == HEAD.field("rail_current").index, str(trips[0])
    trip_cycles = int(HEAD.field("rail_trip_cycles").default)
    assert trips[0].cycle == shorted_at + trip_cycles - 1, str(trips[0])
    _, rail = s.rig.history("rail_switch")
    assert rail[-1] == 0
    _, flags = s.rig.history("fault_flags")
    assert int(flags[-1]) & HeadFaults.RAIL_OVER_CURRENT
    _, closed = s.rig.truth("rail_closed")
    assert closed[-1] == 0.0

    s.rig.plant.set_extra_load(0.0)
    s.rig.set("fault_clear", 1.0)
    cleared_at = s.rig.t
    s.rig.run(seconds=0.02)
    _, rail = s.rig.history("rail_switch")
    assert rail[-1] == 1, "the rail closes again once cleared"
    resets = [r for r in s.rig.emcy if r.code == ERROR_RESET and r.time_s >= cleared_at]
    assert resets, f"expected an EMCY error reset after the clear, got {[str(r) for r in s.rig.emcy]}"


def test_battery_sagging_under_led_load_latches_low_battery(make_scenario) -> None:
    # 45 % charge: 10.62 V open-circuit, 10.52 V with the rail's 0.65 A, under 10.5 V once the LED
    # draws its full 1.05 A more (the internal resistance's drop).
    s = make_scenario(params=head_params(initial_state_of_charge=0.45))
    s.rig.run(seconds=0.1)
    assert not emcy_of(s.rig, "battery_low"), [str(r) for r in s.rig.emcy]
    for colour in ("led_red", "led_green", "led_blue"):
        s.rig.set(colour, 1.0)
    loaded_at = s.rig.cycle
    s.rig.run(seconds=0.1)
    lows = emcy_of(s.rig, "battery_low")
    assert len(lows) == 1, f"expected one EMCY battery_low, got {[str(r) for r in s.rig.emcy]}"
    assert lows[0].object_index == HEAD.field("battery_voltage").index, str(lows[0])
    debounce = int(HEAD.field("battery_low_cycles").default)
    # The LED commands go out before cycle loaded_at's SYNC, the plant draws from the cycle
    # after, whose sample is the first low one: the debounce's last cycle is loaded_at + debounce.
    assert lows[0].cycle == loaded_at + debounce, str(lows[0])
    _, flags = s.rig.history("fault_flags")
    assert int(flags[-1]) & HeadFaults.BATTERY_LOW
    assert not int(flags[-1]) & HeadFaults.RAIL_OVER_CURRENT, "1.65 A is within the rail's limit"


@pytest.mark.requirement("ID_01")
def test_a_rig_for_the_joint_refuses_the_head(private_bus, scenario_dir) -> None:
    """The head's firmware where a rig expects the joint: the rig reads the node's identity
    (0x1018) first and names what answered, before it maps a single PDO."""
    config = RunDescription(
        trace=TraceRun(scenario_dir, trace=False),
        firmware=FirmwareRun(
            executable=resources.HEAD_FIRMWARE,
            node_id=HEAD.board.node.default_node_id,
            boot_timeout_s=BOOT_TIMEOUT_S,
        ),
        rig=RigRun(eds=resources.DEFAULT_EDS, sdo_timeout_s=SCENARIO_SDO_TIMEOUT_S),
    )
    head, joint = HEAD.board.node.product_code, BOARD_TABLE.node.product_code
    refused = pytest.raises(
        NodeSilentError, match=f"product 0x{head:08X}, expected vendor 0x[0-9A-F]{{8}} product 0x{joint:08X}"
    )
    with refused, hil_session(config, table=RigTable(BOARD_TABLE), private_bus=private_bus):
        pass


def test_the_dashboard_generated_from_the_heads_table_draws_every_series_of_its_trace(make_scenario) -> None:
    """The head's real firmware traced: the dashboard any board gets from its table and plant
    (`hilrig view --dashboard board`) shows every series the trace holds and names none it
    lacks, as its hand-made one (`head`) does."""
    from hilrig.cli import main
    from hilrig.observe.dashboard_check import trace_blueprint, trace_gaps, unshown_series
    from hilrig.observe.reader import Trace

    s = make_scenario()
    s.rig.set("led_green", 0.5)  # one command sent, the others never: not expected
    s.rig.run(seconds=0.05)
    assert s.rig.tracer is not None and s.trace is not None
    s.rig.tracer.close()
    trace = Trace.read(s.trace)
    assert trace.board is not None and trace.board.dashboard == "head"
    generated = trace_blueprint("board", trace, trace.board.table())
    assert unshown_series(generated, trace) == []
    assert trace_gaps(trace, {"board": generated}) == []
    assert main(["view", str(s.trace), "--check", "--dashboard", "board"]) == 0
