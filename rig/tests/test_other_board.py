"""Another board than the demo joint through the whole rig: the toy lamp of examples/other-project
(its own table, its EDS generated from it, its plant behind the plant interface) against a node
that answers from that EDS (`FakeJointNode` with the lamp's law), traced. Nothing here is the
joint's: no setpoint stream, other HIL I/O, other truth."""

from __future__ import annotations

import itertools
import sys
from collections.abc import Iterator, Mapping
from pathlib import Path

import can
import numpy as np
import pytest

from hilrig import resources
from hilrig.engine.rig import Rig
from hilrig.observe.sinks import TraceSink
from hilrig.observe.tracer import Tracer
from hilrig.plants.interface import Plant
from hilrig.session.fake_node import FakeJointNode
from hilrig.table import RigTable

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "other-project"
sys.path.insert(0, str(EXAMPLE))
import lamp_plant  # noqa: E402  (the example's own module, as its pytest.ini names it)

_channels = itertools.count()


def lamp_law(inputs: Mapping[str, float | int]) -> dict[str, float | int]:
    """What a lamp firmware does, open loop: PWM from the setpoint, light level from the ADC."""
    return {
        "lamp_pwm": round(float(inputs["light_setpoint"]) * lamp_plant.PWM_FULL_SCALE),
        "light_level": int(inputs["photodiode_adc"]) / lamp_plant.ADC_MAX,
    }


@pytest.fixture
def lamp(tmp_path: Path) -> Iterator[tuple[Rig, Tracer, Path]]:
    files = resources.generated_files(EXAMPLE / "board.toml")
    table = RigTable.load(files.table)
    channel = f"hilrig-lamp-{next(_channels)}"
    rig_bus, fake_bus = (can.Bus(interface="virtual", channel=channel) for _ in range(2))
    fake = FakeJointNode(fake_bus, table=table, eds=files.eds, law=lamp_law)
    trace = tmp_path / "trace.rrd"
    tracer = Tracer(TraceSink.rrd(trace), table, batch_cycles=100, background=False)
    plant = lamp_plant.make_plant(None, seed=1)
    rig = Rig(
        rig_bus,
        table=table,
        eds=files.eds,
        plant=plant,
        tpdo_timeout_s=0.5,
        activity=fake.activity,
        tracer=tracer,
    )
    fake.boot()
    try:
        yield rig, tracer, trace
    finally:
        rig.close()
        fake.close()
        tracer.close()
        rig_bus.shutdown()
        fake_bus.shutdown()


def test_the_lamp_board_runs_in_the_rig_with_its_own_plant_and_truth(lamp: tuple[Rig, Tracer, Path]) -> None:
    rig, tracer, trace = lamp
    assert isinstance(rig.plant, Plant)
    rig.start()
    assert rig.node.node_id == 0x20  # the lamp table's default
    rig.set("light_setpoint", 0.6)  # RPDO2: no setpoint stream on this board, sent as it changes
    rig.run(seconds=0.3)  # six time constants of the lamp
    t, brightness = rig.truth("brightness")
    assert len(t) == 300 and brightness[0] == 0.0
    assert brightness[-1] == pytest.approx(0.6, abs=0.01)
    _, pwm = rig.history("lamp_pwm")
    assert set(pwm[1:].tolist()) == {6000}  # the node's PWM of every cycle after the setpoint
    _, applied = rig.truth("applied_duty")
    assert applied[-1] == 0.6
    _, level = rig.history("light_level")  # the node's reading of the plant's photodiode
    assert np.abs(level[-50:] - brightness[-51:-1]).max() < 0.01  # noise of a few ADC counts
    tracer.close()
    assert trace.stat().st_size > 0


def test_the_lamp_plant_is_deterministic_by_its_seed() -> None:
    def run(seed: int) -> list[int]:
        plant = lamp_plant.make_plant(None, seed)
        frames = []
        for _ in range(20):
            frames.append(plant.sense().photodiode_adc)
            plant.apply((5000,))
            plant.step(1e-3)
        return frames

    assert run(4) == run(4) and run(4) != run(5)


def _lamp_run(lamp: tuple[Rig, Tracer, Path], *, setpoint: bool = True) -> Path:
    rig, tracer, trace = lamp
    rig.start()
    if setpoint:
        rig.set("light_setpoint", 0.6)
    rig.run(seconds=0.05)
    tracer.close()
    return trace


def test_a_lamp_trace_records_its_board_and_its_generated_dashboard(lamp: tuple[Rig, Tracer, Path]) -> None:
    from hilrig.observe.reader import Trace

    trace = Trace.read(_lamp_run(lamp))
    assert trace.board is not None and trace.board.dashboard == "board"
    assert trace.board.table().names == lamp[0].table.names  # the lamp's own, not the joint's
    assert trace.blueprints == 1  # the generated dashboard, sent with the trace


def test_the_generated_dashboard_draws_every_series_of_a_lamp_trace_and_names_none_without_data(
    lamp: tuple[Rig, Tracer, Path],
) -> None:
    from hilrig.observe.blueprints import load_blueprint
    from hilrig.observe.dashboard_check import fitting_dashboards, trace_gaps, unshown_series
    from hilrig.observe.reader import Trace

    rig = lamp[0]
    trace = Trace.read(_lamp_run(lamp))
    fitting = fitting_dashboards(trace)
    assert set(fitting) == {"board"}
    # As sent with the trace before the run (the table's PDOs and the plant's truth), and as
    # `hilrig view` builds it from the trace.
    truth = [*rig.plant.truth_fields, *rig.plant.truth_parameters()]
    before = load_blueprint("board", rig.table, truth=truth)
    for blueprint in (before, fitting["board"]):
        assert unshown_series(blueprint, trace) == []
        assert trace_gaps(trace, {"board": blueprint}) == []
    assert "/truth/brightness" in trace.rows and "/fields/commands/light_setpoint" in trace.rows


def test_a_command_never_sent_is_a_gap_only_of_the_layout_made_before_the_run(
    lamp: tuple[Rig, Tracer, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    from hilrig.cli import main
    from hilrig.observe.blueprints import load_blueprint
    from hilrig.observe.dashboard_check import trace_gaps
    from hilrig.observe.reader import Trace

    trace = _lamp_run(lamp, setpoint=False)
    before = load_blueprint("board", lamp[0].table, truth=lamp[0].plant.truth_fields)
    (gap,) = trace_gaps(Trace.read(trace), {"board": before})
    assert gap.startswith("board / [1] commanded light_setpoint; firmware light_level; true brightness")
    assert gap.endswith("/fields/commands/light_setpoint has no data")
    # From the trace: the scenario never commanded the lamp, which no view then expects.
    assert main(["view", str(trace), "--check"]) == 0
    assert capsys.readouterr().out == f"{trace}: every series board name has data\n"


def test_view_check_passes_on_a_lamp_trace_with_its_setpoint(
    lamp: tuple[Rig, Tracer, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    from hilrig.cli import main

    trace = _lamp_run(lamp)
    assert main(["view", str(trace), "--check"]) == 0
    assert capsys.readouterr().out == f"{trace}: every series board name has data\n"
