"""Fields whose values have names in board.toml (enums, bitsets) carry those names in the trace:
a text entry at `<entity>/label` each time the value changes, next to the number."""

from __future__ import annotations

from pathlib import Path

import can

from hilrig.engine.rig import Rig
from hilrig.observe.batches import value_name
from hilrig.observe.paths import entity_paths, label_path
from hilrig.observe.reader import Trace
from hilrig.observe.sinks import TraceSink
from hilrig.observe.tracer import Tracer
from hilrig.plants import JointParams
from hilrig.session.fake_node import FakeJointNode
from hilrig.table import BOARD_TABLE, ControlMode, FaultFlags, RigTable


def test_an_enum_value_and_a_fault_combination_get_their_names() -> None:
    modes, faults = BOARD_TABLE.enum("control_mode"), BOARD_TABLE.bitset("fault_flags")
    assert value_name(modes, float(ControlMode.TORQUE)) == "torque"
    assert value_name(modes, 7.0) == "7 (no control_mode)"  # protocol-literal: on purpose no mode's number
    assert value_name(faults, 0.0) == "none"
    both = FaultFlags.MOTOR_ENCODER_STALE | FaultFlags.OVER_TEMPERATURE
    lowest_first = sorted(("motor_encoder_stale", "over_temperature"), key=lambda n: faults.bit(n).bit)
    assert value_name(faults, float(both)) == "|".join(lowest_first)
    assert value_name(faults, float(1 << 20)) == "bit 20"  # latched by a newer firmware
    assert value_name(faults, 0.5) == "0.5 (no fault_flags)"  # protocol-literal: on purpose no set of bits
    assert value_name(faults, float("nan")) == "nan (no fault_flags)"


def test_a_traced_run_names_each_new_value_of_an_enum_field(
    fake: FakeJointNode, channel: str, tmp_path: Path
) -> None:
    table = RigTable.load()
    path = tmp_path / "trace.rrd"
    tracer = Tracer(TraceSink.rrd(path), table, batch_cycles=7, background=False, blueprint=None)
    with can.Bus(interface="virtual", channel=channel) as bus:
        rig = Rig(
            bus,
            table=table,
            params=JointParams(),
            seed=1,
            tpdo_timeout_s=0.5,
            activity=fake.activity,
            tracer=tracer,
        )
        try:
            rig.start()
            rig.set("control_mode", ControlMode.VELOCITY)
            rig.run(cycles=10)
            rig.set("control_mode", ControlMode.TORQUE)
            rig.run(cycles=10)
        finally:
            rig.close()
            tracer.close()

    trace = Trace.read(path)
    paths = entity_paths(table)
    mode_labels = [text for text, _level in trace.texts[label_path(paths["control_mode"])]]
    assert mode_labels[-2:] == ["control_mode = velocity", "control_mode = torque"], mode_labels
    mode_numbers = trace.scalars[paths["control_mode"]]
    assert len(mode_numbers) >= 2  # the numbers stay where they were
    fault_labels = trace.texts[label_path(paths["fault_flags"])]
    assert [text for text, _ in fault_labels] == ["fault_flags = none"]  # once: it never changed
    assert trace.texts[label_path(paths["led_pattern"])], "led_pattern (a HIL output) is named too"
    assert "motor_velocity" not in {p.rsplit("/", 2)[-2] for p in trace.texts if p.endswith("/label")}
