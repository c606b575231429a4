"""The scenario fixtures and `--hil-*` options: a private bus per test, the board's firmware on it,
a `Rig` with the board's plant, a candump bus log and a Rerun trace, torn down after the test.

    def test_velocity_step(make_scenario) -> None:
        s = make_scenario(seed=1)
        s.rig.set("velocity_setpoint", 10.0)
        s.rig.run(seconds=0.5)
        s.expect.series("output_velocity").settles_to(10.0, within=0.02)

Which board is the project's (`hil_board`, from the ini options: `hilrig.pytest_plugin.board`).
Every wait is bounded in simulation time; the wall-clock bounds here are hang guards only.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from hilrig.cli import forked
from hilrig.cli.common import bitrate, bus_timing
from hilrig.engine.rig import Rig
from hilrig.engine.robot import MasterHeartbeat
from hilrig.engine.timing import TimingMode
from hilrig.errors import BusUnavailableError
from hilrig.expect import Expect
from hilrig.observe.picture import FailurePictures
from hilrig.observe.sinks import TraceSink, live_sinks_from_environment, parse_live_sink
from hilrig.pytest_plugin.approved import watch
from hilrig.pytest_plugin.board import INI_OPTIONS, HilBoard, board_from_config, report_header
from hilrig.pytest_plugin.labgrid import CONSOLE_LOG, LabgridBoard, labgrid_env_given, open_labgrid_board
from hilrig.session import baremetal, warm
from hilrig.session.builder import (
    BoardInterface,
    HilSession,
    Rider,
    bus_log_path,
    open_session,
)
from hilrig.session.logformats import LOG_FORMATS
from hilrig.session.netns import PrivateBus, private_buses_supported, require_private_buses
from hilrig.session.run import (
    BOOT_TIMEOUT_S,
    REALTIME_FIRMWARE_PERIOD_US,
    BusRun,
    FirmwareRun,
    RigRun,
    RobotRun,
    RunDescription,
    RunOptionError,
    TraceRun,
)
from hilrig.wire.bustime import BUS_PROPERTY, IDEAL, bitrate_text, bus_summary, ideal_label

SCENARIO_SDO_TIMEOUT_S = 5.0
"""Also a hang guard: the firmware on a private bus always answers, but a machine shared with a
second emulated VM has left it unscheduled for over 2 s (1 s and one retry: SdoTimeoutError)."""
REALTIME_RIG_PERIOD_US = 50_000
"""Real-time scenarios (make_scenario(mode="realtime")): the firmware runs free at 100 Hz and the
rig ticks at 20 Hz. Neither keeps 1 kHz inside the software-emulated VM (the ASan firmware missed
over half of its 5 ms deadlines there). The rig's period is what leaves its receive side time to
keep up: at 50 Hz its ticks ran back to back in the VM, the TPDOs it took in fell behind the bus,
and the plant got the firmware's outputs that late. A real board keeps its own period."""
CLI_TIMEOUT_S = 300.0
"""Hang guard for one `hilrig` command in the emulated VM, not a timing check."""
HANG_GUARD_FACTOR = 20
"""A scenario whose recorded duration (hil_durations) is long gets this many times it as its
pytest-timeout bound instead of the run's: a busy host must not read as a hang (the 16-module
robot took 10.4 times its quiet time in a VM beside other work, load 15 to 30). The firmware's
own hangs are the engine's hang guard's to name, in seconds; this bound is for the harness's."""
TABLE_BITRATE = "table"
"""`--hil-timed-bus table` (its default), `make_scenario(bitrate="table")`: the board table's bit
rate."""
RUN_BITRATE = "run"
"""`make_scenario(bitrate=...)`'s default: the run's --hil-timed-bus, unless the scenario is
marked ideal_bus(why)."""
IDEAL_BUS_MARKER = "ideal_bus"
ROBOT_BUS = (
    "a robot (the timed bus times one node's cycle; hilrig.apps.robot_bus: which bit rate a robot needs)"
)
"""Why a `make_robot` run is on the ideal bus, as the summary says it."""
KEEP_ORDER = "HIL_SCENARIO_ORDER"
"""Set to "given": run the scenarios in the order of the command line, not longest first."""


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
        "--hil-timed-bus",
        type=_timed_bus,
        default=TABLE_BITRATE,
        metavar="BITRATE",
        help="lockstep scenarios on a bus with this bit rate: frames that do not fit a cycle "
        f"arrive in a later one; 1M, 500k..., {TABLE_BITRATE} (default: the board table's [node] "
        f"bitrate) or {IDEAL} (every frame in its cycle); a scenario marked "
        f"{IDEAL_BUS_MARKER}(why) runs on the ideal bus whatever this says",
    )
    group.addoption(
        "--hil-physics",
        action="store_true",
        help="simulate the plant for the real board too (a board that takes its sensors from the "
        "bus); default: its own sensors and actuators, the rig only commands and observes",
    )
    group.addoption(
        "--hil-node-id",
        type=lambda text: int(text, 0),
        help="the board's node id (default: its table's)",
    )
    group.addoption(
        "--hil-viewer",
        action="append",
        metavar="WHERE",
        help="also stream every scenario's trace live (repeatable): spawn[:PORT], web[:PORT] or "
        "connect[:URL], as `hilrig sim --viewer` (default: $HIL_TRACE); trace.rrd is always written",
    )
    group.addoption(
        "--hil-bus-log-format",
        type=_bus_log_format,
        default=".log",
        metavar="FORMAT",
        help="every scenario's bus log in this format: "
        + ", ".join(f.lstrip(".") for f in LOG_FORMATS)
        + " (default log, candump); e.g. blf for CANoe, mf4 for CANape",
    )
    group.addoption(
        "--hil-firmware-platform",
        choices=baremetal.FIRMWARE_PLATFORMS,
        default=baremetal.LINUX,
        help="where the firmware of a scenario runs: linux (the firmware process, default) or "
        "qemu-virt (the bare-metal image under qemu-system-arm, `make baremetal`); a scenario "
        "marked firmware_platforms(...) runs once on each platform it names whatever this says",
    )
    for flag, keywords in RunDescription.pytest_options():
        group.addoption(flag, **keywords)
    for name, help_text in INI_OPTIONS:
        parser.addini(name, help_text, default="")


def _timed_bus(text: str) -> int | str | None:
    """--hil-timed-bus: a bit rate, `table` or `ideal` (None); else pytest's one-line usage error."""
    if text.strip().lower() == TABLE_BITRATE:
        return TABLE_BITRATE
    try:
        return bus_timing(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(
            f"expected a bit rate (1M, 500k, 125000), {TABLE_BITRATE} or {IDEAL}, got {text!r}"
        ) from None


def _scenario_bus(
    node: pytest.Item, run: int | str | None, given: int | str | None, board: HilBoard
) -> tuple[int | None, str]:
    """A lockstep run's bus and how the summary names it: its own (`make_scenario(bitrate=...)`),
    else the ideal bus for a scenario marked ideal_bus(why), else the run's (`run`: its
    --hil-timed-bus); `table`: the board's. (bit rate or None, "1 Mbit/s" or "ideal: why")."""
    if given != RUN_BITRATE:
        chosen, why = given, "the scenario's own make_scenario(bitrate=None)"
    elif (marker := node.get_closest_marker(IDEAL_BUS_MARKER)) is not None:
        if len(marker.args) != 1 or not str(marker.args[0]).strip():
            pytest.fail(f"{IDEAL_BUS_MARKER}(why): say why the scenario needs the ideal bus", pytrace=False)
        return None, ideal_label(str(marker.args[0]))
    else:
        chosen, why = run, f"--hil-timed-bus {IDEAL}"
    if chosen == TABLE_BITRATE:
        chosen = board.table.board.node.bitrate
    if chosen is None:
        return None, ideal_label(why)
    return int(chosen), bitrate_text(int(chosen))


def _record_bus(node: pytest.Item | Any, label: str) -> None:
    if (BUS_PROPERTY, label) not in node.user_properties:
        node.user_properties.append((BUS_PROPERTY, label))


FIRMWARE_PLATFORMS_MARKER = "firmware_platforms"


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        f"{FIRMWARE_PLATFORMS_MARKER}(*platforms): run the scenario once on each firmware platform "
        f"({', '.join(baremetal.FIRMWARE_PLATFORMS)}), its id ending in [platform]",
    )
    config.addinivalue_line(
        "markers",
        f"{IDEAL_BUS_MARKER}(why): run the lockstep scenario on the ideal bus (every frame in its "
        "cycle), not the run's --hil-timed-bus, and say why in the run's summary",
    )


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    """How many lockstep scenarios ran on which bus; the ideal bus's with why (the reports'
    BUS_PROPERTY: the controller of an xdist run has them too)."""
    lines = bus_summary(
        [str(value) for name, value in report.user_properties if name == BUS_PROPERTY]
        for reports in terminalreporter.stats.values()
        for report in reports
        if getattr(report, "when", None) == "call"
    )
    if lines:
        terminalreporter.section("the lockstep scenarios' bus")
        for line in lines:
            terminalreporter.line(line)


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    """A scenario marked firmware_platforms("linux", "qemu-virt") once per platform."""
    marker = metafunc.definition.get_closest_marker(FIRMWARE_PLATFORMS_MARKER)
    if marker is None or "hil_firmware_platform" not in metafunc.fixturenames:
        return
    platforms = [baremetal.check_platform(str(platform)) for platform in marker.args]
    metafunc.parametrize("hil_firmware_platform", platforms, indirect=True)


PLATFORM_PROPERTY = "firmware_platform"
"""The JUnit property naming each platform a scenario's firmware ran on (tools/test-summary.py
counts the scenarios of each)."""


def _record_platform(node: pytest.Item | Any, platform: str) -> None:
    if (PLATFORM_PROPERTY, platform) not in node.user_properties:
        node.user_properties.append((PLATFORM_PROPERTY, platform))


@pytest.fixture
def hil_firmware_platform(request: pytest.FixtureRequest) -> str:
    """The platform this scenario's firmware runs on: its firmware_platforms parameter, else
    --hil-firmware-platform."""
    platform = str(getattr(request, "param", None) or request.config.getoption("hil_firmware_platform"))
    _record_platform(request.node, platform)
    return platform


def _bus_log_format(text: str) -> str:
    suffix = "." + text.lower().lstrip(".")
    if suffix not in LOG_FORMATS:
        raise ValueError(text)  # pytest: "argument --hil-bus-log-format: invalid _bus_log_format value"
    return suffix


def pytest_report_header(config: pytest.Config) -> list[str]:
    return report_header(config)


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """With hil_durations: the longest scenarios first (pytest-xdist hands tests out in
    collection order: a long one started last would run alone at the end while the other
    worker idles; a scenario without a recorded duration counts as an average one), and each
    long scenario's hang guard grows with its duration (HANG_GUARD_FACTOR)."""
    spelled = str(config.getini("hil_durations") or "").strip()
    if not spelled:
        return
    base = config.inipath.parent if config.inipath is not None else config.rootpath
    try:
        durations: dict[str, float] = json.loads((base / spelled).read_text())
    except (OSError, ValueError):
        return  # no order to go by: collection order
    guard = config.getoption("timeout", None) if config.pluginmanager.hasplugin("timeout") else None
    if guard:
        for item in items:
            guard_s = HANG_GUARD_FACTOR * durations.get(item.nodeid, 0.0)
            if guard_s > float(guard) and item.get_closest_marker("timeout") is None:
                item.add_marker(pytest.mark.timeout(round(guard_s)))
    if os.environ.get(KEEP_ORDER) == "given":
        return
    average = sum(durations.values()) / len(durations) if durations else 0.0
    items.sort(key=lambda item: -durations.get(item.nodeid, average))  # stable: ties keep their order


# --- The board, the bus, the folder -----------------------------------------------------------
@pytest.fixture(scope="session")
def hil_board(pytestconfig: pytest.Config) -> HilBoard:
    """The project's board (ini options: `hilrig.pytest_plugin.board`); a project may override
    this fixture in its conftest.py instead. A bad option fails each scenario with one line."""
    try:
        return board_from_config(pytestconfig)
    except pytest.UsageError as error:
        problem = str(error)
    pytest.fail(problem, pytrace=False)


@pytest.fixture(scope="session")
def hil_warm_server() -> None:
    """The warm server for helper processes, once per session (of each xdist worker), where
    private buses exist: it imports python-can, canopen and the CLI once, in the background, for
    every scenario's bus recorder and `hilrig` command after it (`hilrig.session.warm`)."""
    if private_buses_supported():
        warm.preload(*forked.CLI_PRELOAD)
        warm.start()


def output_root(config: pytest.Config) -> Path:
    """$HIL_OUT_DIR, else out/ under the run's root folder."""
    return Path(os.environ.get("HIL_OUT_DIR", config.rootpath / "out"))


@pytest.fixture
def scenario_dir(request: pytest.FixtureRequest) -> Path:
    """out/scenarios/<test name>/: the firmware log, bus log and trace of this test."""
    name = re.sub(r"[^A-Za-z0-9_.-]+", "_", request.node.name)
    path = output_root(request.config) / "scenarios" / name
    path.mkdir(parents=True, exist_ok=True)
    return path


@pytest.fixture
def private_bus(hil_warm_server: None) -> Iterator[PrivateBus]:
    """A network namespace with its own vcan0, for this test alone."""
    try:
        require_private_buses(
            "a bus-level scenario", "run pytest through `hilrig bus -- python -m pytest` or on a vcan host"
        )
    except BusUnavailableError as error:
        pytest.fail(str(error), pytrace=False)
    with PrivateBus() as bus:
        yield bus


def run_hilrig(
    private_bus: PrivateBus, *argv: str, timeout_s: float = CLI_TIMEOUT_S
) -> subprocess.CompletedProcess[str]:
    """`hilrig ARGV` on this test's private bus: exit code, stdout and stderr as the console
    script gives them, from a process forked from the warm server (`hilrig.cli.forked`)."""
    return forked.run(argv, namespace_file=private_bus.namespace_file, timeout_s=timeout_s)


def _require_built(board: HilBoard, *platforms: str) -> None:
    firmware = [baremetal.default_image(p) if p == baremetal.QEMU_VIRT else board.firmware for p in platforms]
    missing = [str(path) for path in (*(firmware or [board.firmware]), board.eds) if not path.exists()]
    if missing:
        hint = " (`make baremetal` for qemu-virt)" if baremetal.QEMU_VIRT in platforms else ""
        pytest.fail(
            f"{' and '.join(missing)} missing: build the board's firmware and files first{hint}",
            pytrace=False,
        )


def _pytest_run(config: pytest.Config, run: RunDescription, board: HilBoard) -> RunDescription:
    """`run` with the run options given to pytest (--hil-period-us...), checked as the CLI does."""
    try:
        return RunDescription.from_pytest(config, run, board.table)
    except RunOptionError as error:
        pytest.fail(str(error), pytrace=False)


# --- Scenarios --------------------------------------------------------------------------------
@dataclass
class Scenario:
    """What a scenario test gets: the rig, expectations on its histories, and its evidence.

    `close()` ends it early (rig, firmware with SIGTERM, trace, bus log; the fixture does it
    otherwise), e.g. to read the firmware's stop summary or to start another run on the bus.
    """

    rig: Rig
    expect: Expect
    firmware: Any  # hilrig.session.firmware.Firmware; None: a real board (--hil-interface)
    trace: Path | None
    bus_log: Path
    close: Callable[[], None] = field(default=lambda: None, repr=False)


@pytest.fixture
def make_scenario(
    scenario_dir: Path, hil_board: HilBoard, hil_firmware_platform: str, request: pytest.FixtureRequest
) -> Iterator:
    """Factory: `make_scenario(params=..., seed=...)` opens a HIL session (`hilrig.session.builder`):
    the board's firmware in lockstep on this test's private bus, a candump recorder, a Rerun
    trace and a `Rig` with the board's plant (`hil_plant(params, seed)`), all torn down after
    the test (firmware stopped with SIGTERM, files closed whole).
    `mode="realtime"`: the firmware runs `--mode free` and the rig in real time
    (REALTIME_*_PERIOD_US); with --hil-interface the rig opens that interface instead, talks to
    the real board on it (`physics` as the scenario says), and lockstep scenarios are skipped;
    with labgrid's --lg-env the same, on the target's bus (`hilrig.pytest_plugin.labgrid`).
    `extra_args` go to the firmware's command line; `subdir` keeps one run's evidence apart when
    a test makes several runs one after the other (close the previous one first: one node id per
    bus). `before_start(rig)` configures the node over SDO before the rig reads its PDO mapping
    and starts it (the node is pre-operational, so PDOs may be remapped). `bitrate`: a lockstep
    scenario's timed bus (a bit rate, "table" for the board's, None for the ideal bus; default:
    the run's --hil-timed-bus, itself the table's by default, or the ideal bus for a scenario
    marked ideal_bus(why)); `s.rig.bus_timeline` has its load, backlog and late frames.
    `firmware_platform`: this run's platform instead of the scenario's (`hil_firmware_platform`)."""
    sessions: list[HilSession] = []
    labgrid_consoles: list[tuple[LabgridBoard, Path]] = []

    def make(
        params: object | None = None,
        seed: int = 1,
        trace: bool = True,
        params_file: Path | None = None,
        extra_args: Sequence[str] = (),
        subdir: str | None = None,
        mode: TimingMode | str = TimingMode.LOCKSTEP,
        physics: bool = True,
        before_start: Callable[[Rig], None] | None = None,
        bitrate: int | str | None = RUN_BITRATE,
        firmware_platform: str | None = None,
    ) -> Scenario:
        platform = firmware_platform or hil_firmware_platform
        _record_platform(request.node, platform)
        run_dir = scenario_dir / subdir if subdir else scenario_dir
        realtime = TimingMode(mode) is TimingMode.REALTIME
        config = request.config
        board = None
        node_id = hil_board.node_id
        lab = request.getfixturevalue("hil_labgrid") if labgrid_env_given(config) else None
        if config.getoption("hil_interface") or lab is not None:
            if not realtime:
                given = "--lg-env" if lab is not None else "--hil-interface"
                pytest.skip(f"a lockstep scenario needs the firmware on a private bus ({given} given)")
            if lab is not None:
                board = lab.interface
                labgrid_consoles.append((lab, run_dir / CONSOLE_LOG))
            else:
                bitrate = config.getoption("hil_bitrate")
                board = BoardInterface(
                    config.getoption("hil_interface"), config.getoption("hil_channel"), bitrate
                )
            physics = physics and config.getoption("hil_physics")
            node_id = config.getoption("hil_node_id") or node_id
        timed_bitrate = None
        if not realtime and board is None:
            run_bus = config.getoption("hil_timed_bus")
            timed_bitrate, bus_label = _scenario_bus(request.node, run_bus, bitrate, hil_board)
            _record_bus(request.node, bus_label)
        run = RunDescription(
            trace=TraceRun(
                run_dir,
                trace=trace,
                live=_live_sinks(config) if trace else (),
                bus_log_format=config.getoption("hil_bus_log_format"),
                blueprint=hil_board.dashboard,
            ),
            bus=BusRun(board=board, bitrate=timed_bitrate),
            firmware=FirmwareRun(
                executable=hil_board.firmware,
                platform=platform,
                node_id=node_id,
                period_us=REALTIME_FIRMWARE_PERIOD_US if realtime else None,
                params_file=params_file,
                extra_args=(*hil_board.firmware_args, *extra_args),
                boot_timeout_s=BOOT_TIMEOUT_S,
            ),
            rig=RigRun(
                timing=TimingMode(mode),
                period_us=REALTIME_RIG_PERIOD_US if realtime else None,
                plant=hil_board.plant,
                params=params,
                seed=seed,
                physics=physics,
                eds=hil_board.eds,
                sdo_timeout_s=SCENARIO_SDO_TIMEOUT_S,
            ),
        )
        if board is None:
            _require_built(hil_board, platform)
        # The test's own private bus (a test may send frames of its own on it, e.g. a flood).
        private_bus = request.getfixturevalue("private_bus") if board is None else None
        if not realtime:
            run = _pytest_run(config, run, hil_board)
        session = open_session(run, table=hil_board.table, before_start=before_start, private_bus=private_bus)
        sessions.append(session)
        if board is None and not realtime:
            assert session.rig is not None
            name = subdir or ("main" if len(sessions) == 1 else f"run {len(sessions)}")
            watch(request.node, session.rig, name)
        request.node.hil_evidence = _evidence(run_dir, trace, bus_log_path(run))
        request.node.hil_trace = session.trace_path  # --hil-baseline
        assert session.rig is not None
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
    for lab, path in labgrid_consoles:
        lab.save_console(path)


@pytest.fixture
def make_robot(
    scenario_dir: Path, hil_board: HilBoard, hil_firmware_platform: str, request: pytest.FixtureRequest
) -> Iterator:
    """Factory: `make_robot(n=8)` opens a robot session (`hilrig.session.builder`, `modules=`): the
    firmware started n times on this test's private bus (node ids 1..n, or `node_ids`), one rig
    per module, the chain's mechanics from MuJoCo, the master heartbeat, a candump recorder and
    one Rerun trace (each module under /modules/<id>, the chain in 3D under /robot); returns the
    `HilSession` (its `.robot`), torn down after the test. `riders`: other boards on the same bus
    (`hilrig.session.builder.Rider`, the head module), after the joints. `module_platforms`: node
    ids whose firmware runs on another platform than the scenario's (e.g. {2: "qemu-virt"})."""
    sessions: list[HilSession] = []

    def make(
        n: int = 8,
        *,
        node_ids: Sequence[int] | None = None,
        params: object | None = None,
        seed: int = 1,
        trace: bool = True,
        master: MasterHeartbeat | None = MasterHeartbeat(),  # noqa: B008 (frozen: shared is fine)
        start: bool = True,
        riders: Sequence[Rider] = (),
        module_platforms: dict[int, str] | None = None,
    ) -> HilSession:
        run = RunDescription(
            trace=TraceRun(
                scenario_dir,
                trace=trace,
                live=_live_sinks(request.config) if trace else (),
                bus_log_format=request.config.getoption("hil_bus_log_format"),
            ),
            firmware=FirmwareRun(
                executable=hil_board.firmware,
                platform=hil_firmware_platform,
                extra_args=hil_board.firmware_args,
                boot_timeout_s=BOOT_TIMEOUT_S,
                module_platforms=dict(module_platforms or {}),
            ),
            rig=RigRun(params=params, seed=seed, eds=hil_board.eds, sdo_timeout_s=SCENARIO_SDO_TIMEOUT_S),
            robot=RobotRun(
                tuple(node_ids) if node_ids is not None else n, master=master, riders=tuple(riders)
            ),
        )
        for platform in (module_platforms or {}).values():
            _record_platform(request.node, platform)
        _record_bus(request.node, ideal_label(ROBOT_BUS))
        _require_built(hil_board, hil_firmware_platform, *(module_platforms or {}).values())
        logs = f", firmware logs: {scenario_dir}/firmware-*.log"
        request.node.hil_evidence = _evidence(scenario_dir, trace, bus_log_path(run)) + logs
        session = open_session(
            _pytest_run(request.config, run, hil_board),
            table=hil_board.table,
            private_bus=request.getfixturevalue("private_bus"),
            start=start,
        )
        sessions.append(session)
        if session.robot is not None:
            for module in session.robot.modules:
                prefix = f"robot {len(sessions)} " if len(sessions) > 1 else ""
                watch(request.node, module, f"{prefix}module 0x{module.node.node_id:02X}")
        request.node.hil_trace = session.trace_path  # --hil-baseline
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


def _evidence(scenario_dir: Path, traced: bool, bus_log: Path) -> str:
    parts = [f"trace: {scenario_dir / 'trace.rrd'}"] if traced else []
    parts.append(f"bus log: {bus_log}")
    return ", ".join(parts)


@pytest.fixture(scope="session")
def hil_labgrid(request: pytest.FixtureRequest) -> Iterator[LabgridBoard | None]:
    """The board of labgrid's `target` fixture (its "main" target), powered for the session;
    None without `--lg-env`."""
    if not labgrid_env_given(request.config):
        yield None
        return
    board = request.getfixturevalue("hil_board")
    node_id = request.config.getoption("hil_node_id") or board.node_id
    target = request.getfixturevalue("target")
    try:
        yield from open_labgrid_board(target, node_id, BOOT_TIMEOUT_S)
    except (BusUnavailableError, ValueError) as error:
        pytest.fail(f"labgrid target: {error}", pytrace=False)


__all__ = [
    "BOOT_TIMEOUT_S",
    "REALTIME_FIRMWARE_PERIOD_US",
    "REALTIME_RIG_PERIOD_US",
    "SCENARIO_SDO_TIMEOUT_S",
    "Scenario",
    "hil_board",
    "hil_firmware_platform",
    "hil_labgrid",
    "hil_warm_server",
    "make_robot",
    "make_scenario",
    "output_root",
    "private_bus",
    "pytest_addoption",
    "pytest_collection_modifyitems",
    "pytest_configure",
    "pytest_generate_tests",
    "run_hilrig",
    "scenario_dir",
]
