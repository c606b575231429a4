"""A scenario's Rerun recording, read back with Rerun's own reader: every field the firmware
streamed has one sample per cycle it arrived in, and the faults the scenario triggered are text
log entries. (The web viewer itself is checked by `make check-viewer`, not here.)"""

from __future__ import annotations

import numpy as np
import pytest

from hilrig.table import ControlMode
from hilrig.trace import EMCY_PATH, entity_paths
from hilrig.trace_reader import Trace

pytestmark = pytest.mark.bus


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
