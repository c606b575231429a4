"""Fields no PDO carries, read over SDO every N cycles into the history and the trace
(`Rig.poll_over_sdo`), against the in-process fake node."""

from __future__ import annotations

from pathlib import Path

import can
import pytest

from hilrig.engine.rig import Rig
from hilrig.observe.paths import entity_paths
from hilrig.observe.reader import Trace
from hilrig.observe.sinks import TraceSink
from hilrig.observe.tracer import Tracer
from hilrig.session.fake_node import FakeJointNode
from hilrig.table import RigTable

POLLED = ("spring_constant_estimate", "spring_constant_confidence")


def test_polled_fields_land_in_the_history_and_the_trace_every_nth_cycle(
    fake: FakeJointNode, channel: str, tmp_path: Path
) -> None:
    table = RigTable.load()
    fake.local.sdo["spring_constant_estimate"].raw = 42.5
    path = tmp_path / "trace.rrd"
    tracer = Tracer(TraceSink.rrd(path), table, blueprint=None)
    with can.Bus(interface="virtual", channel=channel) as bus:
        rig = Rig(bus, table=table, tpdo_timeout_s=0.5, activity=fake.activity, tracer=tracer)
        try:
            rig.start()
            rig.poll_over_sdo(POLLED, every_cycles=5)
            rig.run(cycles=12)
            t, values = rig.history("spring_constant_estimate")
            assert list(t) == pytest.approx([0.0, 0.005, 0.010])  # cycles 0, 5 and 10
            assert list(values) == [42.5, 42.5, 42.5]
            rig.poll_over_sdo((), every_cycles=1)  # stop
            rig.run(cycles=10)
            assert len(rig.history("spring_constant_estimate")[0]) == 3
        finally:
            rig.close()
            tracer.close()
    trace = Trace.read(path)
    estimate = entity_paths(table)["spring_constant_estimate"]
    assert trace.cycles[estimate] == [0, 5, 10]
    assert trace.scalars[estimate] == [42.5, 42.5, 42.5]
    assert trace.series_names[estimate].endswith("(SDO, every 5 cycles)")
    assert estimate in trace.stepped  # held between two reads: drawn as steps
    motor_velocity = entity_paths(table)["motor_velocity"]
    assert "SDO" not in trace.series_names[motor_velocity]


def test_a_streamed_field_or_a_bad_rate_is_refused(fake: FakeJointNode, channel: str) -> None:
    with can.Bus(interface="virtual", channel=channel) as bus:
        rig = Rig(bus, table=RigTable.load(), tpdo_timeout_s=0.5, activity=fake.activity)
        try:
            rig.start()
            with pytest.raises(ValueError, match="motor_velocity: in a TPDO already"):
                rig.poll_over_sdo(("motor_velocity",), every_cycles=10)
            with pytest.raises(ValueError, match="every_cycles"):
                rig.poll_over_sdo(POLLED, every_cycles=0)
            with pytest.raises(KeyError, match="did you mean"):
                rig.poll_over_sdo(("spring_constant_estimat",), every_cycles=10)
        finally:
            rig.close()
