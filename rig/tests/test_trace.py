"""Tracing to Rerun: a Rig against the in-process fake node writes a .rrd, which is read back with
Rerun's own reader (`rerun.chunk.RrdReader`) and compared with the rig's own per-cycle history."""

from __future__ import annotations

import itertools
import re
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import can
import pytest
from fake_rig import traced_fake_rig

from boardproto.cia301 import NmtCommand
from hilrig.engine.rig import Rig
from hilrig.errors import FieldNameError, LockstepError, SdoAbortError
from hilrig.observe.blueprints import blueprint_names, load_blueprint
from hilrig.observe.paths import (
    BUS_DELAY_ROOT,
    BUS_EVENTS_PATH,
    BUS_FRAMES_ROOT,
    BUS_LOAD_PATH,
    BUS_RPDOS_PER_CYCLE,
    BUS_TPDOS_PER_CYCLE,
    DIFF_BASE_ROOT,
    DIFF_CAND_ROOT,
    DIFF_EVENTS_PATH,
    DIFF_ROOT,
    EMCY_PATH,
    NMT_PATH,
    SDO_PATH,
    TIMED_BACKLOG_PATH,
    TIMED_LATE_PATH,
    TIMED_LOAD_PATH,
    TRUE_SPRING_STIFFNESS,
    TRUTH_QUANTITIES,
    BusProblem,
    delay_path,
    entity_paths,
    frames_path,
    link_path,
    module_root,
    problem_path,
    truth_path,
    truth_unit,
)
from hilrig.observe.reader import Trace
from hilrig.observe.sinks import SinkKind, TraceSink
from hilrig.observe.tracer import Tracer
from hilrig.observe.viewer import open_trace
from hilrig.plants import JointParams
from hilrig.session.fake_node import FakeJointNode
from hilrig.table import BOARD_TABLE, EmcyCode, RigTable
from hilrig.wire.bustime import TimedBus
from hilrig.wire.framebits import frame_bits_worst_case

PARAMS = JointParams.fast_thermal()
CYCLES = 47  # not a multiple of the batch: the last, partial batch must be written by close()
BATCH = 10
BATCH_ENDS = [*range(BATCH - 1, CYCLES - 1, BATCH), CYCLES - 1]
"""The last cycle of each batch: a step series sent as its changes has a row there."""
_channels = itertools.count()


@pytest.fixture(scope="module")
def table() -> RigTable:
    return RigTable.load()


@dataclass
class Run:
    rig: Rig
    fake: FakeJointNode
    tracer: Tracer
    path: Path


class _RowsOnly(Tracer):
    """A tracer that is not shown the rig's History: it pivots every cycle's rows itself."""

    def on_history(self, history: object) -> None:
        pass


@pytest.fixture(
    params=[(Tracer, True), (Tracer, False), (_RowsOnly, True)], ids=["background", "inline", "rows"]
)
def traced(request: pytest.FixtureRequest, table: RigTable, tmp_path: Path) -> Iterator[Run]:
    channel = f"hilrig-trace-{next(_channels)}"
    rig_bus, fake_bus = (can.Bus(interface="virtual", channel=channel) for _ in range(2))
    fake = FakeJointNode(fake_bus, table=table)
    path = tmp_path / "scenario" / "trace.rrd"
    kind, background = request.param
    tracer = kind(TraceSink.rrd(path), table, batch_cycles=BATCH, background=background, blueprint="faults")
    rig = Rig(
        rig_bus, table=table, params=PARAMS, seed=3, tpdo_timeout_s=0.5, activity=fake.activity, tracer=tracer
    )
    fake.boot()
    try:
        yield Run(rig, fake, tracer, path)
    finally:
        rig.close()
        fake.close()
        tracer.close()
        rig_bus.shutdown()
        fake_bus.shutdown()


def _scenario(run: Run) -> None:
    """Start, run with a setpoint step, one SDO write, one refused SDO write, one EMCY, stop/start."""
    rig = run.rig
    rig.start()
    rig.set("velocity_setpoint", 5.0)
    rig.at(0.020, lambda r: r.set("velocity_setpoint", -2.0))
    rig.run(cycles=12)
    rig.set("velocity_kp", 0.25)
    with pytest.raises(SdoAbortError):
        rig.set("velocity_kp", 99.0)
    over_temperature = BOARD_TABLE.emcy("over_temperature")
    about = BOARD_TABLE.field("winding_temperature").index.to_bytes(2, "little") + bytes(3)
    run.fake.send_emcy(EmcyCode.OVER_TEMPERATURE, over_temperature.error_register, about)
    rig.run(cycles=CYCLES - 12)
    run.tracer.close()


def test_every_field_has_one_sample_per_cycle_it_was_exchanged_in(traced: Run, table: RigTable) -> None:
    _scenario(traced)
    trace = Trace.read(traced.path)
    paths = entity_paths(table)
    history = traced.rig.driver.history
    exchanged = [name for name in table.names if history.has_received(name) or history.has_sent(name)]
    assert {"motor_duty", "winding_temperature", "velocity_setpoint", "thermistor_adc"} <= set(exchanged)
    for name in exchanged:
        t, values = traced.rig.history(name)
        path = paths[name]
        assert trace.scalars[path] == pytest.approx(values.astype(float).tolist()), name
        assert trace.times[path] == pytest.approx(t.tolist()), name
        assert trace.cycles[path] == [round(x * 1000) for x in t], name
        assert trace.series_names[path] == f"{name} [{table.entry(name).unit}]"
    # One received every cycle, one only every 10th SYNC (TPDO8), one sent every cycle.
    assert len(trace.scalars[paths["motor_duty"]]) == CYCLES
    assert len(trace.scalars[paths["winding_temperature"]]) == CYCLES // 10
    assert trace.scalars[paths["velocity_setpoint"]] == [5.0] * 20 + [-2.0] * (CYCLES - 20)
    # The SDO write is in the trace at the time it was made; the refused one is not.
    assert trace.scalars[paths["velocity_kp"]] == [0.25]
    assert trace.cycles[paths["velocity_kp"]] == [12]


@pytest.mark.filterwarnings("ignore:RRD file has no footer")  # a copy taken while being written
@pytest.mark.parametrize(
    "traced", [(Tracer, True), (Tracer, False)], ids=["background", "inline"], indirect=True
)
def test_the_series_are_named_in_the_file_before_the_first_cycle(
    traced: Run, table: RigTable, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The start names every series and lets Rerun write those static chunks then, not beside
    # the run's first cycles (`Tracer.on_configured`). The file is copied the moment the start's
    # settle() returns: after it the start goes on logging (the NMT start), and a message being
    # appended would be a torn end to read.
    on_disk = tmp_path / "at-settle.rrd"
    settle = traced.tracer.settle

    def settle_then_copy() -> bool:
        settled = settle()
        assert traced.rig.cycle == 0
        on_disk.write_bytes(traced.path.read_bytes())
        return settled

    monkeypatch.setattr(traced.tracer, "settle", settle_then_copy)
    traced.rig.start()
    assert on_disk.exists(), "the start did not wait for Rerun (Tracer.settle) before the first cycle"
    names = Trace.read(on_disk).series_names
    paths = entity_paths(table)
    for name in ("motor_velocity", "velocity_setpoint", "motor_duty"):
        assert paths[name] in names, f"{name} not named in {traced.path} before the first cycle"
    assert truth_path("load_velocity_rad_s") in names


def test_ground_truth_is_logged_every_cycle_next_to_the_fields(traced: Run) -> None:
    _scenario(traced)
    trace = Trace.read(traced.path)
    for quantity in TRUTH_QUANTITIES[:-1]:
        assert trace.cycles[truth_path(quantity)] == list(range(CYCLES)), quantity
    _, true_velocity = traced.rig.truth("load_velocity")
    assert trace.scalars[truth_path("load_velocity_rad_s")] == pytest.approx(true_velocity.tolist())
    # The plant's spring constant, a parameter: a step series, its first cycle and each batch's last.
    stiffness = truth_path(TRUE_SPRING_STIFFNESS)
    assert trace.cycles[stiffness] == [0, *BATCH_ENDS]
    assert trace.at_cycles(stiffness, range(CYCLES)) == [PARAMS.spring_stiffness_nm_per_rad] * CYCLES
    assert stiffness in trace.stepped
    assert trace.series_names[truth_path("load_velocity_rad_s")] == "true load_velocity_rad_s [rad/s]"


def test_faults_and_nmt_changes_are_text_log_entries_with_severity(traced: Run) -> None:
    _scenario(traced)
    trace = Trace.read(traced.path)
    (emcy,) = trace.texts[EMCY_PATH]
    assert emcy[1] == "ERROR"
    assert emcy[0].startswith("EMCY 0x4210") and "about 0x2104" in emcy[0]
    (abort,) = trace.texts[SDO_PATH]
    assert abort[1] == "WARN"
    assert "0x06090031" in abort[0] and "velocity_kp" in abort[0] and "cycle 12" in abort[0]
    nmt = trace.texts[NMT_PATH]
    assert ("NMT OPERATIONAL (command START) at t = 0 s", "INFO") in nmt


def test_frames_per_cycle_of_every_pdo_and_the_pdo_configuration_are_in_the_trace(traced: Run) -> None:
    _scenario(traced)
    trace = Trace.read(traced.path)
    node = traced.rig.node
    tpdos = [p for p in node.tpdos.values() if p.enabled and p.names]
    rpdos = [p for p in node.rpdos.values() if p.enabled and p.names]
    every_cycle = list(range(CYCLES))
    # Sensor inputs and the setpoint stream every cycle; RPDO3 (control mode) only when it
    # changes, which this scenario never does: a PDO never seen on the bus has no series.
    streamed = [p for p in rpdos if p.number in (1, 2)]
    for pdo in (*tpdos, *streamed):
        path = frames_path(pdo)
        expected = [float(pdo in streamed or pdo.due_at_sync(c + 1)) for c in every_cycle]
        assert trace.at_cycles(path, every_cycle) == expected, pdo.label  # zeros where it did not come
        # A step series: a row where the count changes and at each batch's last cycle, no other.
        changes = [c for c in every_cycle if c == 0 or expected[c] != expected[c - 1]]
        assert trace.cycles[path] == sorted({*changes, *BATCH_ENDS}), pdo.label
        assert trace.series_names[path] == f"{pdo.label} [frames]"
    framed = {p for p in trace.scalars if p.startswith(BUS_FRAMES_ROOT)}
    assert framed == {frames_path(p) for p in (*tpdos, *streamed)}
    # TPDO8 (winding temperature) every 10th SYNC: the sum per cycle shows it.
    sums = trace.at_cycles(BUS_TPDOS_PER_CYCLE, every_cycle)
    assert sums[9] == sums[0] + 1 and len(set(sums)) == 2
    assert set(trace.at_cycles(BUS_RPDOS_PER_CYCLE, every_cycle)) == {len(streamed)}
    lines = [text for text, level in trace.texts[BUS_EVENTS_PATH] if level == "INFO"]
    assert len(lines) == len(tpdos) + len(rpdos)
    assert any(line.startswith("TPDO8 (0x") and "every 10th SYNC: " in line for line in lines), lines


def test_held_values_are_drawn_as_steps_measured_ones_as_lines(traced: Run, table: RigTable) -> None:
    _scenario(traced)
    trace = Trace.read(traced.path)
    paths = entity_paths(table)
    # A setpoint, a parameter and a state with named values hold until they change: steps (a
    # command sent only when it changes would otherwise be drawn as a slope between two sends).
    for name in ("velocity_setpoint", "velocity_kp", "fault_flags", "led_pattern"):
        assert paths[name] in trace.stepped, name
    assert BUS_TPDOS_PER_CYCLE in trace.stepped
    # Frame counts zoomed out: the band from the fewest to the most, so one missing frame shows.
    assert {BUS_TPDOS_PER_CYCLE, BUS_RPDOS_PER_CYCLE} <= trace.banded
    assert paths["velocity_setpoint"] not in trace.banded
    for name in ("motor_velocity", "joint_torque", "motor_duty"):
        assert paths[name] not in trace.stepped, name
    assert truth_path("load_velocity_rad_s") not in trace.stepped


def test_a_missing_tpdo_is_a_warning_on_the_bus_events(traced: Run) -> None:
    traced.rig.start()
    traced.rig.run(cycles=3)
    traced.fake.drop = lambda sync_number, tpdo_number: tpdo_number == 1
    with pytest.raises(LockstepError, match="TPDO1"):
        traced.rig.run(cycles=1)
    traced.tracer.close()
    trace = Trace.read(traced.path)
    warnings = [text for text, level in trace.texts[BUS_EVENTS_PATH] if level == "WARN"]
    assert len(warnings) == 1 and "cycle 3" in warnings[0] and "did not arrive" in warnings[0], warnings


def test_every_plot_of_every_dashboard_has_one_unit(table: RigTable) -> None:
    """One unit per axis: a plot never mixes rad/s with N*m, or a duty with degrees."""
    from dashboards import BLUEPRINTS, OTHER_BOARD_BLUEPRINTS, blueprint

    unit_of = {path: table.entry(name).unit for name, path in entity_paths(table).items()}
    unit_of |= {truth_path(q): truth_unit(q) for q in TRUTH_QUANTITIES}
    unit_of |= {BUS_TPDOS_PER_CYCLE: "frames", BUS_RPDOS_PER_CYCLE: "frames", BUS_LOAD_PATH: "%"}
    unit_of |= {problem_path(problem): "frames" for problem in BusProblem}
    unit_of |= {TIMED_LOAD_PATH: "%", TIMED_BACKLOG_PATH: "frames", TIMED_LATE_PATH: "frames"}
    for name in BLUEPRINTS:
        if name in OTHER_BOARD_BLUEPRINTS:  # another board's table: test_the_head_dashboard...
            continue
        for view in _views(blueprint(name, table).root_container):
            contents = view.contents if isinstance(view.contents, list) else []
            # A robot module's fields are one board's under /modules/<id>; a comparison's under
            # /base, /cand and /diff.
            shown = [path for path in contents if not path.startswith("+ ")]
            paths = [re.sub(r"^/(modules/\d+|base|cand|diff)(?=/)", "", path) for path in shown]
            units = {unit_of[path] for path in paths}
            assert len(units) <= 1, f"{name}: {view.name} mixes {sorted(units)}"


def test_nmt_stop_is_a_warning_at_its_cycle(traced: Run) -> None:
    traced.rig.start()
    traced.rig.run(cycles=3)
    traced.rig.nmt(NmtCommand.STOP)
    traced.tracer.close()
    trace = Trace.read(traced.path)
    stops = [(text, level) for text, level in trace.texts[NMT_PATH] if "STOPPED (command" in text]
    assert stops == [("NMT STOPPED (command STOP) at t = 0.003 s", "WARN")]
    index = [text for text, _ in trace.texts[NMT_PATH]].index(stops[0][0])
    assert trace.cycles[NMT_PATH][index] == 3


def test_the_trace_carries_the_chosen_blueprint(traced: Run) -> None:
    traced.rig.start()
    traced.rig.run(cycles=2)
    traced.tracer.close()
    assert Trace.read(traced.path).blueprints == 1


def test_blueprints_show_only_paths_the_tracer_logs(table: RigTable) -> None:
    from dashboards import BLUEPRINTS, OTHER_BOARD_BLUEPRINTS, blueprint
    from dashboards.robot import DEFAULT_NODE_IDS

    one_board = {*entity_paths(table).values(), *(truth_path(q) for q in TRUTH_QUANTITIES)}
    # A robot's: every module's fields under its root, and the links of its 3D view.
    robot = {module_root(n) + path for n in DEFAULT_NODE_IDS for path in one_board}
    robot |= {link_path(k) for k in range(len(DEFAULT_NODE_IDS) + 1)}
    logged = one_board | robot | {BUS_TPDOS_PER_CYCLE, BUS_RPDOS_PER_CYCLE, f"{BUS_FRAMES_ROOT}/TPDO1"}
    logged |= {BUS_LOAD_PATH, delay_path("TPDO1"), *(problem_path(problem) for problem in BusProblem)}
    logged |= {TIMED_LOAD_PATH, TIMED_BACKLOG_PATH, TIMED_LATE_PATH}  # a run on the timed bus
    # A comparison (`hilrig diff`): both runs' series under /base and /cand, cand - base under /diff.
    logged |= {root + path for root in (DIFF_BASE_ROOT, DIFF_CAND_ROOT, DIFF_ROOT) for path in one_board}
    logged.add(DIFF_EVENTS_PATH)
    dashboards = {"overview", "tuning", "thermal", "faults", "bus", "robot", "diff", "head", "board"}
    assert set(blueprint_names()) == dashboards == set(BLUEPRINTS)
    for name in set(BLUEPRINTS) - set(OTHER_BOARD_BLUEPRINTS):
        views = list(_views(blueprint(name, table).root_container))
        assert views, name
        for view in views:
            contents = view.contents if isinstance(view.contents, list) else [view.contents]
            for path in contents:
                if "$origin" not in path and not path.startswith("+ "):  # "+ /events/**": a query
                    assert path in logged, f"{name}: {view.name} shows {path}, which is never logged"
            origin = str(view.origin)
            assert any(p.startswith(origin) for p in logged) or origin.startswith("/events"), name


def test_a_blueprint_name_typo_lists_close_matches() -> None:
    with pytest.raises(FieldNameError, match="did you mean 'thermal'"):
        load_blueprint("thermals")  # imports dashboards/ whatever the cwd (so does this test)


def test_sinks_parse_from_the_command_line(tmp_path: Path) -> None:
    assert TraceSink.parse(f"rrd:{tmp_path}/t.rrd") == TraceSink.rrd(tmp_path / "t.rrd")
    assert TraceSink.parse("spawn") == TraceSink.spawn()
    assert TraceSink.parse("connect:rerun+http://host:1234/proxy").url == "rerun+http://host:1234/proxy"
    web = TraceSink.parse("web:8080")
    assert (web.kind, web.port) == (SinkKind.WEB, 8080)
    with pytest.raises(FieldNameError, match="did you mean 'spawn'"):
        TraceSink.parse("spwan")
    with pytest.raises(ValueError, match="needs a path"):
        TraceSink.parse("rrd")


def test_open_trace_opens_the_file_with_the_named_blueprint(tmp_path: Path, table: RigTable) -> None:
    with Tracer(TraceSink.rrd(tmp_path / "t.rrd"), table, blueprint=None):
        pass
    command = open_trace(tmp_path / "t.rrd", blueprint="thermal", launch=False)
    assert isinstance(command, list)
    assert command[:3] == [sys.executable, "-m", "rerun"]
    assert command[3] == str(tmp_path / "t.rrd")
    import rerun as rr

    (store,) = rr.chunk.RrdReader(command[4]).blueprints()
    assert store.application_id == "hilrig"
    # Served, the trace is sent in once the server listens: a file on rerun's command line keeps
    # a thread of the server busy for as long as it serves.
    served = open_trace(tmp_path / "t.rrd", blueprint="thermal", web=True, web_port=9191, launch=False)
    assert served[3:] == [
        "--web-viewer", "--web-viewer-port", "9191", "--port", "9876", "--bind", "127.0.0.1"
    ]
    with pytest.raises(FileNotFoundError):
        open_trace(tmp_path / "missing.rrd", launch=False)


def test_the_rig_does_not_import_rerun_without_a_tracer() -> None:
    code = (
        "import sys, hilrig.engine.rig, hilrig.observe.tracer; "
        "assert 'rerun' not in sys.modules, 'rerun imported'"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert result.returncode == 0, result.stderr


def _views(container: object) -> Iterator[object]:
    for part in getattr(container, "contents", []):
        if hasattr(part, "class_identifier"):
            yield part
        else:
            yield from _views(part)


def test_real_time_stamps_read_back_to_the_nanosecond(tmp_path: Path, table: RigTable) -> None:
    # A real-time tick lands at any nanosecond (21.595240 ms here), which Python's timedelta
    # cannot hold: the reader must still give it back.
    path = tmp_path / "realtime.rrd"
    tracer = Tracer(TraceSink.rrd(path), table, batch_cycles=1, background=False)
    ticks = [0.0, 0.021595240, 0.083000017]
    for cycle, t in enumerate(ticks):
        tracer.log_cycle(cycle, t, {"motor_duty_command": 0.1 * cycle}, {}, None)
    tracer.close()
    trace = Trace.read(path)
    [duty_path] = [p for p in trace.scalars if p.endswith("/motor_duty_command")]
    assert trace.times[duty_path] == pytest.approx(ticks, abs=1e-9)
    assert trace.scalars[duty_path] == pytest.approx([0.0, 0.1, 0.2])


def test_a_rigs_cycles_are_counted_and_handed_over_in_whole_batches(traced: Run) -> None:
    rig, tracer = traced.rig, traced.tracer
    rig.start()
    rig.run(cycles=BATCH + 3)
    assert (tracer.cycles_logged, tracer.pending_cycles) == (BATCH + 3, 3)
    tracer.close()
    assert (tracer.cycles_logged, tracer.pending_cycles) == (BATCH + 3, 0)
    with pytest.raises(RuntimeError, match="Tracer is closed"):  # not one cycle more, unseen
        rig.run(cycles=1)


@pytest.mark.parametrize("latency_s", [None, 0.0], ids=["file-default", "live-latency-0"])
def test_batches_wait_for_their_size_unless_a_live_latency_is_due(
    tmp_path: Path, table: RigTable, latency_s: float | None
) -> None:
    # A file alone waits for whole batches (each costs one send per entity); with a latency bound
    # (a live viewer's default is LIVE_LATENCY_S) a batch goes out once that much time passed:
    # 0 s here, so every cycle goes at once. Either way close() leaves nothing behind.
    path = tmp_path / "batches.rrd"
    tracer = Tracer(TraceSink.rrd(path), table, batch_cycles=1000, max_latency_s=latency_s, background=False)
    assert tracer.max_latency_s == latency_s
    for cycle in range(5):
        tracer.log_cycle(cycle, cycle * 0.001, {"motor_duty_command": 0.1 * cycle}, {}, None)
        assert tracer.pending_cycles == (cycle + 1 if latency_s is None else 0)
    tracer.close()
    trace = Trace.read(path)
    [duty_path] = [p for p in trace.scalars if p.endswith("/motor_duty_command")]
    assert trace.scalars[duty_path] == pytest.approx([0.0, 0.1, 0.2, 0.3, 0.4])


def test_a_live_sink_gets_a_latency_bound_by_default(tmp_path: Path) -> None:
    from hilrig.observe.sinks import LIVE_LATENCY_S, default_latency

    rrd = TraceSink.rrd(tmp_path / "a.rrd")
    assert default_latency([rrd]) is None
    assert default_latency([rrd, TraceSink.spawn()]) == LIVE_LATENCY_S
    assert default_latency([TraceSink.connect()]) == LIVE_LATENCY_S
    assert default_latency([TraceSink.serve_web()]) == LIVE_LATENCY_S


def test_a_dashboard_check_names_every_series_without_data(traced: Run, table: RigTable) -> None:
    """`dashboard_check.missing_series`: what a view names but the trace lacks, line by line."""
    from dashboards import blueprint
    from hilrig.observe.dashboard_check import missing_series

    _scenario(traced)
    trace = Trace.read(traced.path)
    assert trace.rows[NMT_PATH] == len(trace.texts[NMT_PATH])
    faults = missing_series(blueprint("faults", table), trace, name="faults")
    # fault_clear goes out only when written (`hilrig sim` polls it), control_mode (RPDO3) only
    # when it changes, which this scenario never does; the rest is there.
    paths = entity_paths(table)
    assert faults == [
        f"faults / fault flags and fault clear: {paths['fault_clear']} has no data",
        f"faults / control mode: {paths['control_mode']} has no data",
    ]
    # A tracer following the Rig's History names the series of every PDO the node has at the
    # first cycle, RPDO3's control_mode included: a name is no row, so the gap is still reported.
    assert (paths["control_mode"] in trace.series_names) == (not isinstance(traced.tracer, _RowsOnly))
    bus = missing_series(blueprint("bus", table), trace, name="bus")
    if isinstance(traced.tracer, _RowsOnly):  # a cycle's rows say what came, not when it came
        assert bus == [f"bus / each TPDO's delay after its SYNC [ms]: nothing under {BUS_DELAY_ROOT}"], bus
    else:
        assert bus == [], bus


def test_the_truth_paths_name_every_quantity_of_the_joint_state() -> None:
    """hilrig.observe.paths lists the truth quantities itself (it imports no plant, so that the
    dashboards import nothing else of hilrig): the list must stay the JointState's."""
    from dataclasses import fields

    from hilrig.observe.paths import TRUE_SPRING_STIFFNESS, TRUTH_QUANTITIES
    from hilrig.plants import JointState

    state = tuple(f.name for f in fields(JointState) if f.name != "time_s")
    assert (*state, TRUE_SPRING_STIFFNESS) == TRUTH_QUANTITIES


def test_a_robot_module_names_and_colours_its_own_series(tmp_path: Path) -> None:
    """On one plot of every module, each module's series carry its number and its colour: the
    commanded ones lighter, the truth darker (tracer rooted at /modules/<id>)."""
    import rerun as rr

    from hilrig.observe.batches import MODULE_COLOURS

    table = RigTable.load()
    path = tmp_path / "robot.rrd"
    tracer = Tracer(TraceSink.rrd(path), table, batch_cycles=10, background=False, root="/modules/3")
    with traced_fake_rig(tracer, table) as rig:
        rig.set("velocity_setpoint", 2.0)
        rig.run(cycles=5)
    colours: dict[str, int] = {}
    for chunk in rr.chunk.RrdReader(path).stream():
        batch = chunk.to_record_batch()
        if chunk.is_static and "SeriesLines:colors" in batch.schema.names:
            colours[chunk.entity_path] = batch.column("SeriesLines:colors").to_pylist()[0][0]
    names = Trace.read(path).series_names
    measured, commanded = (
        "/modules/3/fields/virtual_sensors/output_velocity",
        "/modules/3/fields/commands/velocity_setpoint",
    )
    truth = "/modules/3/truth/load_velocity_rad_s"
    assert names[measured] == "module 3 output_velocity [rad/s]"
    assert names[truth] == "module 3 true load_velocity_rad_s [rad/s]"
    red, green, blue = MODULE_COLOURS[2]
    assert colours[measured] == (red << 24) | (green << 16) | (blue << 8) | 0xFF
    lighter, darker = colours[commanded] >> 24, colours[truth] >> 24
    assert darker < red < lighter


def test_bus_load_per_10_ms_and_each_tpdos_delay_after_its_sync_are_in_the_trace(traced: Run) -> None:
    """From a lockstep run's History (`hilrig.observe.busmeter`): the worst-case bits of each
    cycle's SYNC, RPDOs and TPDOs, per 10 ms window in % of 1 Mbit/s; each TPDO's delay after its
    SYNC by the exchange's clock, one per cycle it came in. A tracer not shown the History (the
    real-time driver's rows) has the load and counts, not the delays."""
    _scenario(traced)
    trace = Trace.read(traced.path)
    node = traced.rig.node
    tpdos = [p for p in node.tpdos.values() if p.enabled and p.names]
    streamed = [p for p in node.rpdos.values() if p.enabled and p.names and p.number in (1, 2)]
    bits = [0] * ((CYCLES + 9) // 10)
    for c in range(CYCLES):
        frames = [1] + [p.length for p in streamed] + [p.length for p in tpdos if p.due_at_sync(c + 1)]
        bits[c // 10] += sum(frame_bits_worst_case(n) for n in frames)
    assert trace.cycles[BUS_LOAD_PATH] == list(range(0, CYCLES, 10))
    assert trace.scalars[BUS_LOAD_PATH] == pytest.approx([b / (0.010 * 1_000_000) * 100 for b in bits])
    assert trace.series_names[BUS_LOAD_PATH] == "bus load [% of 1 Mbit/s]"
    for pdo in tpdos if not isinstance(traced.tracer, _RowsOnly) else ():
        path = delay_path(f"TPDO{pdo.number}")
        assert trace.cycles[path] == [c for c in range(CYCLES) if pdo.due_at_sync(c + 1)], pdo.label
        assert all(0 < delay < 500 for delay in trace.scalars[path]), (pdo.label, trace.scalars[path])
    for problem in BusProblem:  # the fake node answers every SYNC in time
        assert trace.scalars[problem_path(problem)] == [0.0] * len(bits), problem
    if isinstance(traced.tracer, _RowsOnly):
        assert not any(path.startswith(BUS_DELAY_ROOT) for path in trace.scalars)


def test_the_timed_bus_load_backlog_and_late_frames_are_in_the_trace(traced: Run) -> None:
    """A run on the timed bus (`hilrig.engine.bustiming`): per cycle its load in % of the bit
    rate (the fake node's full mapping overloads 1 Mbit/s: 100 %, never more), the frames waiting
    and those delivered late, from the History's timeline; a tracer not shown the History has
    none of them."""
    rig = traced.rig
    rig.start()
    rig.driver.time_bus(TimedBus(1_000_000, rig.driver.period_us))
    rig.run(cycles=CYCLES)
    traced.tracer.close()
    trace = Trace.read(traced.path)
    if isinstance(traced.tracer, _RowsOnly):
        assert TIMED_LOAD_PATH not in trace.scalars
        return
    timeline = rig.bus_timeline
    assert timeline is not None
    assert trace.cycles[TIMED_LOAD_PATH] == list(timeline.cycles())
    assert trace.scalars[TIMED_LOAD_PATH] == pytest.approx([100.0 * load for load in timeline.load])
    assert max(trace.scalars[TIMED_LOAD_PATH]) == 100.0
    assert trace.scalars[TIMED_BACKLOG_PATH] == [float(n) for n in timeline.backlog_frames]
    assert max(trace.scalars[TIMED_BACKLOG_PATH]) > 0
    assert trace.scalars[TIMED_LATE_PATH] == [float(n) for n in timeline.late_frames]
