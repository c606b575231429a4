"""Fixtures for the hardware-in-the-loop scenarios: a private bus per test, the real firmware
process on it, and a CANopen master (the `canopen` library) built from the generated EDS."""

from __future__ import annotations

import json
import os
import re
import subprocess
import threading
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import can
import canopen
import pytest

from boardproto.cia301 import NmtState, heartbeat_cob_id
from hilrig.cli import forked
from hilrig.cli.common import bitrate
from hilrig.engine.rig import Rig
from hilrig.engine.robot import MasterHeartbeat
from hilrig.errors import BusUnavailableError
from hilrig.expect import Expect
from hilrig.observe.picture import FailurePictures
from hilrig.observe.sinks import TraceSink, live_sinks_from_environment, parse_live_sink
from hilrig.plants import JointParams
from hilrig.session import warm
from hilrig.session.builder import BoardInterface, HilSession, SessionConfig, open_session
from hilrig.session.buslog import BusRecorder
from hilrig.session.firmware import DEFAULT_EXECUTABLE, Firmware, parse_stop_line
from hilrig.session.netns import PrivateBus, private_buses_supported, require_private_buses
from hilrig.table import RigTable

REPO = Path(__file__).resolve().parent.parent
EDS = REPO / "build" / "protocol" / "board.eds"
NODE_ID = 0x10
# A hang guard for start-up inside the software-emulated VM (ASan build), not a timing check.
BOOT_TIMEOUT_S = 60.0
# Also a hang guard: the firmware on a private bus always answers, but a machine shared with a
# second emulated VM has left it unscheduled for over 2 s (1 s and one retry: SdoTimeoutError).
SCENARIO_SDO_TIMEOUT_S = 5.0
# Real-time scenarios (make_scenario(mode="realtime")): the firmware runs free at 100 Hz and the
# rig ticks at 20 Hz. Neither keeps 1 kHz inside the software-emulated VM (measured there: the
# ASan firmware missed over half of its 5 ms deadlines). The rig's period is what leaves its
# receive thread time to keep up: at 50 Hz its ticks ran back to back (a tick costs 20 to 80 ms
# in the VM), the TPDOs it took in fell up to 0.5 s behind the bus (bus log against the rig's
# history), and the plant got the firmware's duty that late. A real board keeps its own period.
REALTIME_FIRMWARE_PERIOD_US = 10_000
REALTIME_RIG_PERIOD_US = 50_000
TABLE = RigTable.load()


DURATIONS = REPO / "tests" / ".test_durations"
"""Each scenario's recorded duration (`make durations`), for pytest-split and the order below."""


HANG_GUARD_S = 600.0
"""pytest-timeout's bound on a scenario (pytest.ini): a hang guard that dumps every thread's
stack, never a timing check."""
HANG_GUARD_FACTOR = 10
"""A scenario whose recorded duration is long gets this many times it instead: the 8-module gait
(about 3 minutes in the VM) ran past 600 s with one busy loop beside the VM, a busy host read as
a hang. Ten times what it takes on a quiet machine is still a bound a real hang reaches."""
KEEP_ORDER = "HIL_SCENARIO_ORDER"
"""Set to "given": run the scenarios in the order of the command line (`make mutate` puts the
scenarios that killed most mutants first), not longest first."""


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The longest scenarios first: pytest-xdist hands tests out in collection order, and the
    8-module gait (over 3 minutes in the VM) started last would run alone at the end while the
    other worker idles. A scenario without a recorded duration counts as an average one. Each
    long scenario's hang guard grows with its duration (HANG_GUARD_FACTOR)."""
    try:
        durations: dict[str, float] = json.loads(DURATIONS.read_text())
    except (OSError, ValueError):
        return  # no order to go by: collection order
    for item in items:
        guard_s = HANG_GUARD_FACTOR * durations.get(item.nodeid, 0.0)
        if guard_s > HANG_GUARD_S and item.get_closest_marker("timeout") is None:
            item.add_marker(pytest.mark.timeout(round(guard_s)))
    if os.environ.get(KEEP_ORDER) == "given":
        return
    average = sum(durations.values()) / len(durations) if durations else 0.0
    items.sort(key=lambda item: -durations.get(item.nodeid, average))  # stable: ties keep their order


CLI_TIMEOUT_S = 300.0
"""Hang guard for one `hilrig` command in the emulated VM, not a timing check."""


@pytest.fixture(scope="session", autouse=True)
def warm_helper_server() -> None:
    """Start the warm server for helper processes at the first test of a session (of each xdist
    worker): it imports python-can, canopen and the CLI once, in the background, for every
    scenario's bus recorder and `hilrig` command after it (`hilrig.session.warm`)."""
    if private_buses_supported():
        warm.preload(*forked.CLI_PRELOAD)
        warm.start()


def run_hilrig(
    private_bus: PrivateBus, *argv: str, timeout_s: float = CLI_TIMEOUT_S
) -> subprocess.CompletedProcess[str]:
    """`hilrig ARGV` on this test's private bus: exit code, stdout and stderr as the console
    script gives them, from a process forked from the warm server (`hilrig.cli.forked`)."""
    return forked.run(argv, namespace_file=private_bus.namespace_file, timeout_s=timeout_s)


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("hil", "hardware in the loop")
    group.addoption(
        "--hil-interface",
        help="run the real-time scenarios against a board on this python-can interface "
        "(socketcan, pcan, kvaser, slcan...) instead of the firmware on a private vcan; "
        "lockstep scenarios are skipped",
    )
    group.addoption("--hil-channel", help="the interface's channel, e.g. can0 or PCAN_USBBUS1")
    group.addoption(
        "--hil-bitrate", type=bitrate, help="bit rate for interfaces that set it (e.g. 1M, 500k, 125000)"
    )
    group.addoption(
        "--hil-physics",
        action="store_true",
        help="simulate the plant for the real board too (a board that takes its sensors from the "
        "bus); default: its own sensors and motor, the rig only commands and observes",
    )
    group.addoption(
        "--hil-node-id", type=lambda text: int(text, 0), help=f"the board's node id (default {NODE_ID:#x})"
    )
    group.addoption(
        "--hil-viewer",
        action="append",
        metavar="WHERE",
        help="also stream every scenario's trace live (repeatable): spawn[:PORT], web[:PORT] or "
        "connect[:URL], as `hilrig sim --viewer` (default: $HIL_TRACE); trace.rrd is always written",
    )


def output_root() -> Path:
    return Path(os.environ.get("HIL_OUT_DIR", REPO / "out"))


@pytest.fixture
def scenario_dir(request: pytest.FixtureRequest) -> Path:
    """out/scenarios/<test name>/: the firmware log, bus log and trace of this test."""
    name = re.sub(r"[^A-Za-z0-9_.-]+", "_", request.node.name)
    path = output_root() / "scenarios" / name
    path.mkdir(parents=True, exist_ok=True)
    return path


@pytest.fixture
def private_bus() -> Iterator[PrivateBus]:
    """A network namespace with its own vcan0, for this test alone."""
    try:
        require_private_buses(
            "a bus-level scenario", "run it with `make test` or `tools/with-vcan -- .venv/bin/pytest tests`"
        )
    except BusUnavailableError as error:
        pytest.fail(str(error), pytrace=False)
    with PrivateBus() as bus:
        yield bus


@dataclass
class NodeUnderTest:
    """The running firmware and a CANopen master talking to it on a private bus."""

    bus: can.BusABC
    network: canopen.Network
    node: canopen.RemoteNode
    firmware: Firmware
    bus_log: Path
    recorder: BusRecorder

    def wait_for(
        self,
        cob_id: int,
        timeout_s: float = 30.0,
        after_subscribing: Callable[[], object] | None = None,
        data: bytes | None = None,
    ) -> can.Message:
        """The next frame with this COB-ID (and these data bytes, if given; bounded wait: a
        hang guard, not a timing check). `after_subscribing` sends the request that frame
        answers: only once we listen, so an answer faster than this thread cannot be missed."""
        got: list[can.Message] = []
        arrived = threading.Event()
        wanted = data

        def on_frame(can_id: int, data: bytearray, timestamp: float) -> None:
            if wanted is not None and bytes(data) != wanted:
                return
            if not arrived.is_set():
                got.append(can.Message(arbitration_id=can_id, data=bytes(data), timestamp=timestamp))
                arrived.set()

        self.network.subscribe(cob_id, on_frame)
        try:
            if after_subscribing is not None:
                after_subscribing()
            if not arrived.wait(timeout_s):
                self.firmware.check()
                raise AssertionError(f"expected a frame with COB-ID {cob_id:#05x}, got none in {timeout_s} s")
            return got[0]
        finally:
            self.network.unsubscribe(cob_id, on_frame)


def start_node(private_bus: PrivateBus, scenario_dir: Path, params_file: Path | None = None) -> NodeUnderTest:
    if not DEFAULT_EXECUTABLE.exists() or not EDS.exists():
        pytest.fail(f"{DEFAULT_EXECUTABLE} or {EDS} missing: run `make build` first", pytrace=False)
    bus_log = scenario_dir / "bus.log"
    recorder = BusRecorder(private_bus.open(), bus_log)
    bus = private_bus.open(receive_own_messages=True)
    network = canopen.Network(bus)
    network.connect()
    node = network.add_node(canopen.RemoteNode(NODE_ID, str(EDS)))
    booted = threading.Event()
    boot_up = bytes([NmtState.INITIALISING])
    network.subscribe(
        heartbeat_cob_id(NODE_ID), lambda can_id, data, ts: booted.set() if data[:1] == boot_up else None
    )
    firmware = Firmware(
        private_bus, node_id=NODE_ID, log_path=scenario_dir / "firmware.log", params_file=params_file
    )
    firmware.start()
    if not booted.wait(BOOT_TIMEOUT_S):
        firmware.check()
        raise AssertionError(
            f"no boot-up message from node {NODE_ID:#x} within {BOOT_TIMEOUT_S} s; "
            f"firmware log: {firmware.log_path}"
        )
    return NodeUnderTest(
        bus=bus, network=network, node=node, firmware=firmware, bus_log=bus_log, recorder=recorder
    )


def stop_node(under_test: NodeUnderTest) -> int | None:
    code = under_test.firmware.stop()
    under_test.network.disconnect()
    under_test.bus.shutdown()
    under_test.recorder.close()
    return code


@pytest.fixture
def node_under_test(private_bus: PrivateBus, scenario_dir: Path) -> Iterator[NodeUnderTest]:
    """The firmware in lockstep mode on a private bus, booted (pre-operational), with a
    canopen master; on teardown the firmware must stop cleanly on SIGTERM."""
    under_test = start_node(private_bus, scenario_dir)
    try:
        yield under_test
    finally:
        code = stop_node(under_test)
    assert code == 0, (
        f"firmware did not exit cleanly on SIGTERM ({code}); log: {under_test.firmware.log_path}"
    )


@dataclass
class Scenario:
    """What a scenario test gets: the rig, expectations on its histories, and its evidence.

    `close()` ends it early (rig, firmware with SIGTERM, trace, bus log; the fixture does it
    otherwise), e.g. to read the firmware's stop summary or to start another run on the bus.
    """

    rig: Rig
    expect: Expect
    firmware: Firmware | None  # None: a real board (--hil-interface)
    trace: Path | None
    bus_log: Path
    close: Callable[[], None] = field(default=lambda: None, repr=False)


@pytest.fixture
def make_scenario(scenario_dir: Path, request: pytest.FixtureRequest) -> Iterator:
    """Factory: `make_scenario(params=..., seed=...)` opens a HIL session (`hilrig.session.builder`):
    the firmware in lockstep on this test's private bus, a candump recorder, a Rerun trace and
    a `Rig`, all torn down after the test (firmware stopped with SIGTERM, files closed whole).
    `mode="realtime"`: the firmware runs `--mode free` and the rig in real time
    (REALTIME_*_PERIOD_US); with --hil-interface the rig opens that interface instead, talks to
    the real board on it (`physics` as the scenario says), and lockstep scenarios are skipped.
    `extra_args` go to the firmware's command line; `subdir` keeps one run's evidence apart when
    a test makes several runs one after the other (close the previous one first: one node id per
    bus). `before_start(rig)` configures the node over SDO before the rig reads its PDO mapping
    and starts it (the node is pre-operational, so PDOs may be remapped)."""
    sessions: list[HilSession] = []

    def make(
        params: JointParams | None = None,
        seed: int = 1,
        trace: bool = True,
        params_file: Path | None = None,
        extra_args: Sequence[str] = (),
        subdir: str | None = None,
        mode: str = "lockstep",
        physics: bool = True,
        before_start: Callable[[Rig], None] | None = None,
    ) -> Scenario:
        run_dir = scenario_dir / subdir if subdir else scenario_dir
        realtime = mode == "realtime"
        config = request.config
        board = None
        node_id = NODE_ID
        if config.getoption("hil_interface"):
            if not realtime:
                pytest.skip("a lockstep scenario needs the firmware on a private bus (--hil-interface given)")
            bitrate = config.getoption("hil_bitrate")
            board = BoardInterface(
                config.getoption("hil_interface"), config.getoption("hil_channel"), bitrate
            )
            physics = physics and config.getoption("hil_physics")
            node_id = config.getoption("hil_node_id") or NODE_ID
        session_config = SessionConfig(
            out_dir=run_dir,
            live=_live_sinks(config) if trace else (),
            params=params,
            seed=seed,
            node_id=node_id,
            mode=mode,
            period_us=REALTIME_RIG_PERIOD_US if realtime else 1000,
            firmware_period_us=REALTIME_FIRMWARE_PERIOD_US if realtime else 1000,
            physics=physics,
            trace=trace,
            board=board,
            eds=EDS,
            params_file=params_file,
            extra_args=tuple(extra_args),
            boot_timeout_s=BOOT_TIMEOUT_S,
            sdo_timeout_s=SCENARIO_SDO_TIMEOUT_S,
        )
        if board is None and (not DEFAULT_EXECUTABLE.exists() or not EDS.exists()):
            pytest.fail(f"{DEFAULT_EXECUTABLE} or {EDS} missing: run `make build` first", pytrace=False)
        # The test's own private bus (a test may send frames of its own on it, e.g. a flood).
        private_bus = request.getfixturevalue("private_bus") if board is None else None
        session = open_session(
            session_config, table=TABLE, before_start=before_start, private_bus=private_bus
        )
        sessions.append(session)
        request.node.hil_evidence = _evidence(run_dir, trace)
        request.node.hil_trace = session.trace_path  # hilrig's plugin: --hil-baseline
        return Scenario(
            rig=session.rig,
            expect=Expect(
                session.rig, evidence=request.node.hil_evidence, picture=FailurePictures(run_dir / "pictures")
            ),
            firmware=session.firmware,
            trace=session.trace_path,
            bus_log=session.bus_log,
            close=session.close,
        )

    yield make
    for session in reversed(sessions):
        session.close()


@pytest.fixture
def make_robot(scenario_dir: Path, request: pytest.FixtureRequest) -> Iterator:
    """Factory: `make_robot(n=8)` opens a robot session (`hilrig.session.builder`, `modules=`): the
    firmware started n times on this test's private bus (node ids 1..n, or `node_ids`), one rig
    per module, the chain's mechanics from MuJoCo, the master heartbeat, a candump recorder and
    one Rerun trace (each module under /modules/<id>, the chain in 3D under /robot); returns the
    `HilSession` (its `.robot`), torn down after the test."""
    sessions: list[HilSession] = []

    def make(
        n: int = 8,
        *,
        node_ids: Sequence[int] | None = None,
        params: JointParams | None = None,
        seed: int = 1,
        trace: bool = True,
        master: MasterHeartbeat | None = MasterHeartbeat(),  # noqa: B008 (frozen: shared is fine)
        start: bool = True,
    ) -> HilSession:
        config = SessionConfig(
            out_dir=scenario_dir,
            modules=tuple(node_ids) if node_ids is not None else n,
            live=_live_sinks(request.config) if trace else (),
            params=params,
            seed=seed,
            trace=trace,
            eds=EDS,
            master=master,
            start=start,
            boot_timeout_s=BOOT_TIMEOUT_S,
            sdo_timeout_s=SCENARIO_SDO_TIMEOUT_S,
        )
        if not DEFAULT_EXECUTABLE.exists() or not EDS.exists():
            pytest.fail(f"{DEFAULT_EXECUTABLE} or {EDS} missing: run `make build` first", pytrace=False)
        logs = f", firmware logs: {scenario_dir}/firmware-*.log"
        request.node.hil_evidence = _evidence(scenario_dir, trace) + logs
        session = open_session(config, table=TABLE, private_bus=request.getfixturevalue("private_bus"))
        sessions.append(session)
        request.node.hil_trace = session.trace_path  # hilrig's plugin: --hil-baseline
        return session

    yield make
    for session in reversed(sessions):
        session.close()


def _live_sinks(config: pytest.Config) -> list[TraceSink]:
    """--hil-viewer, else $HIL_TRACE; a bad spelling stops the run with one line."""
    spelled = config.getoption("hil_viewer")
    try:
        if spelled:
            return [parse_live_sink(text) for text in spelled]
        return live_sinks_from_environment()
    except ValueError as error:
        raise pytest.UsageError(f"--hil-viewer: {error}") from None


def _evidence(scenario_dir: Path, traced: bool) -> str:
    parts = [f"trace: {scenario_dir / 'trace.rrd'}"] if traced else []
    parts.append(f"bus log: {scenario_dir / 'bus.log'}")
    return ", ".join(parts)


_failed_evidence: list[str] = []


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo) -> Iterator:
    outcome = yield
    report = outcome.get_result()
    evidence = getattr(item, "hil_evidence", None)
    if report.failed and evidence:
        report.sections.append(("scenario evidence", evidence))
        _failed_evidence.append(f"FAILED {item.nodeid}: {evidence}")


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    if _failed_evidence:
        terminalreporter.section("failed scenarios: where to look")
        for line in _failed_evidence:
            terminalreporter.line(line)


def stop_summary(firmware: Firmware) -> dict[str, int]:
    """The counters of the firmware's stop line (printed on SIGTERM), by name:
    {"cycles": 812, "overruns": 0, "frames received": 4100, "ignored": 3, "malformed": 0, ...}."""
    parsed = parse_stop_line(firmware.log_path.read_text(errors="replace"))
    assert parsed is not None, f"no stop summary in {firmware.log_path}:\n{firmware.log_tail()}"
    return parsed[1]
