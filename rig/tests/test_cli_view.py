"""`hilrig view`: a saved trace in the viewer with a dashboard (the viewer itself is started in
rig/tests/test_web_viewer.py through the same `open_trace`)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from hilrig.cli import main
from hilrig.observe.blueprints import blueprint_names
from hilrig.session.fake_node import FakeJointNode

REPO = Path(__file__).resolve().parents[2]


def test_list_names_every_dashboard(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["view", "--list"]) == 0
    assert capsys.readouterr().out.split() == list(blueprint_names())
    assert {"overview", "tuning", "thermal", "faults"} <= set(blueprint_names())


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        ([], "name the trace to open"),
        (["missing.rrd"], "trace missing.rrd does not exist"),
        (["{rrd}", "--dashboard", "tunning"], "did you mean 'tuning'"),
        (["{log}"], "bus.log does not end in .rrd"),
        (["{empty}"], "empty.rrd is not a Rerun recording"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(
    argv: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rrd, log, empty = tmp_path / "t.rrd", tmp_path / "bus.log", tmp_path / "empty.rrd"
    rrd.write_bytes(b"RRF2")  # how a recording starts
    log.write_text("")
    empty.write_bytes(b"")
    code = main(["view", *(a.format(rrd=rrd, log=log, empty=empty) for a in argv)])
    err = capsys.readouterr().err
    assert code == 2
    assert len(err.splitlines()) == 1 and message in err, err


def test_the_older_spelling_still_works() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "dashboards", "--list"], capture_output=True, text=True, cwd=REPO, check=False
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == list(blueprint_names())


def _fake_node_trace(path: Path, channel: str, fake: FakeJointNode) -> None:
    """A few cycles of a Rig against the fake node on `channel`, traced to `path`."""
    import can

    from hilrig.engine.rig import Rig
    from hilrig.observe.sinks import TraceSink
    from hilrig.observe.tracer import Tracer
    from hilrig.plants import JointParams
    from hilrig.table import ControlMode, RigTable

    table = RigTable.load()
    tracer = Tracer(TraceSink.rrd(path), table, blueprint=None)
    params = JointParams.fast_thermal()
    with can.Bus(interface="virtual", channel=channel) as bus:
        rig = Rig(
            bus, table=table, params=params, seed=3, tpdo_timeout_s=0.5, activity=fake.activity, tracer=tracer
        )
        try:
            rig.start()
            rig.set("control_mode", ControlMode.VELOCITY)
            rig.run(cycles=20)
        finally:
            rig.close()
            tracer.close()


def test_check_lists_the_series_a_dashboard_names_that_the_trace_lacks(
    fake: FakeJointNode, channel: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    trace = tmp_path / "trace.rrd"
    _fake_node_trace(trace, channel, fake)
    # No SDO poll, no EMCY, no abort in this run: those views are empty, and said so.
    assert main(["view", str(trace), "--check"]) == 1
    gaps = capsys.readouterr().out.splitlines()
    estimate = "/fields/modules/spring_constant_estimate"
    assert f"tuning / spring constant [N*m/rad]: estimate vs true: {estimate} has no data" in gaps
    assert "bus / SDO aborts: nothing under /events/sdo" in gaps
    assert not [gap for gap in gaps if gap.startswith("overview / ")], gaps  # it is all in PDOs
    assert main(["view", str(trace), "--check", "--dashboard", "overview"]) == 0
    assert capsys.readouterr().out == f"{trace}: every series overview name has data\n"
