"""A scenario's Rerun recording, read back with Rerun's own reader: every field the firmware
streamed has one sample per cycle it arrived in, the faults the scenario triggered are text log
entries, and every series every dashboard names has data. (The dashboards in the web viewer are
shown in headless Chromium on this scenario's trace after this stage: tools/run-tests, stage 4.)"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import FULL_MAPPING_ON_THE_IDEAL_BUS

from hilrig.errors import SdoAbortError
from hilrig.observe.blueprints import dashboard_fields
from hilrig.observe.dashboard_check import fitting_dashboards, trace_gaps
from hilrig.observe.paths import EMCY_PATH, SDO_PATH, entity_paths
from hilrig.observe.reader import Trace
from hilrig.table import ControlMode

POLL_EVERY = 100
"""Cycles between SDO reads of what a dashboard plots but no PDO carries (as `hilrig sim`)."""

pytestmark = [pytest.mark.bus, FULL_MAPPING_ON_THE_IDEAL_BUS]


@pytest.mark.requirement("RIG_02")
def test_a_scenario_trace_holds_every_streamed_field_and_its_faults(make_scenario) -> None:
    s = make_scenario()
    s.rig.set("control_mode", ControlMode.VELOCITY)
    s.rig.set("velocity_setpoint", 1.0)
    s.rig.run(seconds=0.1)
    s.rig.pause_rpdo(2)  # the setpoint stream stops: the watchdog trips, EMCY 0x8100
    s.rig.run(seconds=0.1)
    assert s.rig.tracer is not None and s.trace is not None
    s.rig.tracer.close()  # flushes the last batch; the fixture's second close is a no-op
    trace = Trace.read(s.trace)
    paths = entity_paths(s.rig.table)
    checked = 0
    for name in (
        "motor_velocity",
        "output_velocity",
        "joint_torque",
        "motor_duty_command",
        "safe_state",
        "fault_flags",
        "watchdog_tripped",
        "winding_temperature",
        "motor_duty",
    ):
        times, _ = s.rig.history(name)
        path = paths[name]
        assert len(trace.scalars[path]) == len(times), (
            f"{name}: expected {len(times)} samples in {s.trace}, got {len(trace.scalars[path])}"
        )
        np.testing.assert_allclose(trace.times[path], times, atol=1e-9)
        checked += 1
    assert checked == 9
    emcy_texts = [text for text, _level in trace.texts[EMCY_PATH]]
    assert any("0x8100" in text for text in emcy_texts), f"expected the watchdog EMCY in {emcy_texts}"


@pytest.mark.requirement("RIG_02")
def test_every_series_every_dashboard_names_has_data_on_a_firmware_trace(make_scenario) -> None:
    """Each control mode in turn, a parameter write the node refuses, the setpoint stream
    stopped (EMCY): the trace of the real firmware gives every view of every joint dashboard
    data. Its trace.rrd is what the browser stage shows in every dashboard."""
    s = make_scenario()
    rig = s.rig
    rig.poll_over_sdo(rig.in_no_pdo(dashboard_fields(rig.table)), every_cycles=POLL_EVERY)
    for mode, setpoint, value in (
        (ControlMode.VELOCITY, "velocity_setpoint", 4.0),
        (ControlMode.TORQUE, "torque_setpoint", 0.3),
        (ControlMode.POSITION, "position_setpoint", 0.5),
    ):
        rig.set("control_mode", mode)
        rig.set(setpoint, value)
        rig.run(seconds=0.2)
    with pytest.raises(SdoAbortError):
        rig.set("velocity_kp", 99.0)  # above its range in board.toml
    rig.pause_rpdo(2)  # the setpoint stream stops: the watchdog trips, EMCY 0x8100
    rig.run(seconds=0.1)
    assert rig.tracer is not None and s.trace is not None
    rig.tracer.close()
    trace = Trace.read(s.trace)
    dashboards = fitting_dashboards(trace)
    assert set(dashboards) == {"overview", "tuning", "thermal", "faults", "bus"}
    gaps = trace_gaps(trace, dashboards)
    assert gaps == [], f"{s.trace}: series without data:\n" + "\n".join(gaps)
    assert trace.texts[SDO_PATH] and trace.texts[EMCY_PATH]
