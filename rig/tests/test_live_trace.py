"""Live traces: where `hilrig sim` (and the scenarios, through $HIL_TRACE) stream while running.

The live test runs the real command, `hilrig sim --board ... --viewer web:PORT:GRPC`, in a
thread of this process against the in-process fake node on a python-can `virtual` bus (the
command's real-board path: no firmware, real time), and headless Chromium shows the recording
growing in the served web viewer while the run is still going.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

import can
import pytest

from hilrig.apps.demo import DEFAULT_POLL_EVERY
from hilrig.cli import main
from hilrig.observe.browser import WAIT_S, ViewerPage, browser_missing, free_port, wait_until_listening
from hilrig.observe.paths import WALL_TIME_TIMELINE
from hilrig.observe.sinks import (
    LIVE_TRACE_ENV,
    SinkKind,
    TraceSink,
    live_sinks_from_environment,
    parse_live_sink,
    web_viewer_url,
)
from hilrig.observe.viewer import ViewerProcess
from hilrig.session.fake_node import FakeJointNode
from hilrig.table import RigTable

NO_BROWSER = browser_missing()


# --- Spelling --------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "spelled",
    ["spawn", "spawn:9877", "web", "web:8080", "web:8080:9999", "connect", "connect:rerun+http://h:1/proxy"],
)
def test_a_live_sink_reads_back_as_it_prints(spelled: str) -> None:
    sink = parse_live_sink(spelled)
    assert parse_live_sink(str(sink)) == sink


def test_a_web_sink_takes_both_ports() -> None:
    sink = parse_live_sink("web:8080:9999")
    assert (sink.kind, sink.port, sink.url) == (SinkKind.WEB, 8080, "9999")


@pytest.mark.parametrize(
    ("spelled", "message"),
    [
        ("rrd:out/x.rrd", "the trace file is always written"),
        ("spwan", "did you mean 'spawn'"),
        ("web:abc", "web\\[:PORT\\[:GRPC_PORT\\]\\]"),
    ],
)
def test_a_bad_live_sink_says_what_to_write(spelled: str, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        parse_live_sink(spelled)


def test_the_environment_names_live_sinks() -> None:
    assert live_sinks_from_environment({}) == []
    sinks = live_sinks_from_environment({LIVE_TRACE_ENV: "connect, spawn:9000"})
    assert sinks == [TraceSink.connect(), TraceSink.spawn(9000)]
    with pytest.raises(ValueError, match=f"\\${LIVE_TRACE_ENV}: 'rrd:x'"):
        live_sinks_from_environment({LIVE_TRACE_ENV: "rrd:x"})


@pytest.mark.parametrize(
    ("argv", "environment", "message"),
    [
        (["--viewer", "rrd:x.rrd"], {}, "the trace file is always written"),
        (["--viewer", "web", "--no-trace"], {}, "choose one"),
        ([], {LIVE_TRACE_ENV: "bogus"}, "$HIL_TRACE: 'bogus'"),
    ],
)
def test_sim_refuses_a_bad_viewer_in_one_line(
    argv: list[str],
    environment: dict[str, str],
    message: str,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
) -> None:
    for name, value in environment.items():
        monkeypatch.setenv(name, value)
    # --board: no firmware is needed to get this far; the check comes before any bus is opened.
    code = main(["sim", "--board", "-i", "virtual", "--out", str(tmp_path), *argv])
    err = capsys.readouterr().err
    assert code == 2
    assert len(err.splitlines()) == 1 and message in err, err


# --- Live, in the browser --------------------------------------------------------------------
SCENARIO = """
from pathlib import Path

from hilrig.table import ControlMode

STOP = Path({stop!r})
HANG_GUARD_S = 600.0


def scenario(rig):
    rig.set("control_mode", ControlMode.VELOCITY)
    rig.set("velocity_setpoint", 2.0)
    while not STOP.exists() and rig.t < HANG_GUARD_S:
        rig.run(seconds=0.05)
"""


@pytest.mark.skipif(NO_BROWSER is not None, reason=str(NO_BROWSER))
@pytest.mark.timeout(600)
def test_sim_streams_to_a_web_viewer_that_shows_the_recording_grow_while_it_runs(tmp_path: Path) -> None:
    table = RigTable.load()
    channel = f"live-{os.getpid()}"
    stop = tmp_path / "stop"
    scenario = tmp_path / "until_stopped.py"
    scenario.write_text(SCENARIO.format(stop=str(stop)))
    web_port, grpc_port = free_port(), free_port()
    fake_bus = can.Bus(interface="virtual", channel=channel)
    fake = FakeJointNode(fake_bus, table=table)
    fake.boot()  # its heartbeat tells the rig it is there, whenever the rig's bus opens
    argv = [
        "sim",
        "--board",
        "-i",
        "virtual",
        "-c",
        channel,
        "--period-us",
        "10000",
        "--scenario",
        str(scenario),
        "--out",
        str(tmp_path / "out"),
        "--viewer",
        f"web:{web_port}:{grpc_port}",
        "--no-keep-serving",
    ]
    result: list[int] = []
    run = threading.Thread(target=lambda: result.append(main(argv)), name="hilrig-sim")
    run.start()
    url = web_viewer_url(web_port, grpc_port)

    def still_running() -> None:  # the web server comes up once the session has imported rerun
        assert run.is_alive(), f"hilrig sim ended with {result} before serving {url}"

    try:
        with ViewerPage(url, server_check=still_running) as viewer:
            first = viewer.wait_for(
                lambda s: s.timeline_ends.get(WALL_TIME_TIMELINE, 0) > 0 or not run.is_alive(),
                "the live recording on the wall-clock timeline",
            )
            assert run.is_alive(), "the run ended before the viewer showed anything"
            started = first.timeline_ends[WALL_TIME_TIMELINE]
            later = viewer.wait_for(
                lambda s: s.timeline_ends.get(WALL_TIME_TIMELINE, 0) > started,
                "the recording to grow",
            )
            assert run.is_alive(), "the recording grew only after the run had ended"
    finally:
        stop.touch()
        run.join(timeout=WAIT_S)
        fake.close()
        fake_bus.shutdown()
    assert not run.is_alive(), "hilrig sim did not end after its scenario"
    assert result == [0]
    assert later.timeline_ends[WALL_TIME_TIMELINE] > started
    from hilrig.observe.paths import entity_paths
    from hilrig.observe.reader import Trace

    # The file is written beside the live sink, with what a dashboard plots but no PDO carries
    # read over SDO (every DEFAULT_POLL_EVERY cycles, cycle 0 first).
    trace = Trace.read(tmp_path / "out" / "trace.rrd")
    estimate = entity_paths(table)["spring_constant_estimate"]
    assert trace.cycles[estimate][:1] == [0], sorted(trace.cycles)
    assert trace.series_names[estimate].endswith(f"(SDO, every {DEFAULT_POLL_EVERY} cycles)")
    summary = (tmp_path / "out" / "summary.txt").read_text()
    assert web_viewer_url(web_port, grpc_port) in summary


def _ctrl_c_ends_it() -> None:
    """In the server's process: SIGINT ends it again. A shell starts background jobs (make test
    under `&`, some CI runners) with SIGINT ignored, and children inherit that."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.filterwarnings("ignore:RRD file has no footer")  # the server's file is a stream
@pytest.mark.parametrize("command", ["record", "watch"])
def test_a_boards_pdos_stream_live_to_a_viewer(command: str, tmp_path: Path) -> None:
    """`hilrig record|watch --viewer connect:URL` against the fake node (we are its master: NMT
    start, SYNC): a Rerun server that saves what it receives gets the decoded fields on the wall
    clock."""
    from hilrig.observe.paths import entity_paths
    from hilrig.observe.reader import Trace

    table = RigTable.load()
    saved = tmp_path / "viewer.rrd"
    grpc_port = free_port()
    server = [sys.executable, "-m", "rerun", "--serve-web", "--port", str(grpc_port)]
    viewer = ViewerProcess(
        [*server, "--web-viewer-port", str(free_port()), "--save", str(saved)],
        process_group=0,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        preexec_fn=_ctrl_c_ends_it,
    )
    channel = f"live-{command}-{os.getpid()}"
    fake_bus = can.Bus(interface="virtual", channel=channel)
    fake = FakeJointNode(fake_bus, table=table)
    try:
        wait_until_listening(grpc_port, viewer)
        fake.boot()
        bus = ["-i", "virtual", "-c", channel]
        live = ["--viewer", f"connect:rerun+http://127.0.0.1:{grpc_port}/proxy"]
        if command == "record":
            argv = ["record", str(tmp_path / "bus.log"), "--count", "300"]
        else:
            argv = ["watch", "--pdo-from-eds", "--count", "5", "--interval", "0.2"]
        code = main([*argv, *bus, "--nmt-start", "--sync-period-ms", "5", *live])
        assert code == 0
    finally:
        fake.close()
        fake_bus.shutdown()
        viewer.send_signal(signal.SIGINT)  # the server finishes its file on Ctrl-C
        viewer.wait(timeout=WAIT_S)
    trace = Trace.read(saved)
    motor_velocity = entity_paths(table)["motor_velocity"]
    assert len(trace.scalars[motor_velocity]) > 10, sorted(trace.scalars)
    assert min(trace.times[motor_velocity]) > 1e9, "stamped with the wall clock (Unix seconds)"
