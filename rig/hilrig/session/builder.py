"""One place that assembles a HIL session: the firmware on a private bus, the bus log, the tracer
and the rig (or, for a real board, the rig on the board's interface with no firmware), opened in
order and closed in reverse on one `contextlib.ExitStack`. Used by the pytest fixtures,
`hilrig sim` / `make run`, the bench and the trace bench::

    with hil_session(RunDescription(TraceRun(Path("out/run")), rig=RigRun(seed=1))) as session:
        session.rig.set("control_mode", ControlMode.VELOCITY)  # from hilrig.table
        session.rig.run(seconds=1.0)
    # firmware stopped (SIGTERM, its stop line in out/run/firmware.log), out/run/bus.log and
    # out/run/trace.rrd whole

A real board: `RunDescription(TraceRun(out_dir), bus=BusRun(board=BoardInterface("socketcan", "can0")),
rig=RigRun(timing=TimingMode.REALTIME))` (`hilrig.session.run`: the one description of a run).

A robot: `RunDescription(..., robot=RobotRun(8))` starts the firmware 8 times (node ids 1..8, or a
list), each with its own log (firmware-<id>.log) and parameter file (params-<id>.bin), and hands
over `session.robot` (`hilrig.engine.robot.Robot`): one bus, one SYNC, the chain's mechanics from MuJoCo,
each module's trace under /modules/<id>.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import can

from boardproto.cia301 import emcy_cob_id
from hilrig.engine.rig import Rig, TimingMode
from hilrig.engine.robot import Robot, module_ids
from hilrig.session import baremetal
from hilrig.session.buslog import RecorderProcess, whole_file_logger
from hilrig.session.firmware import Firmware
from hilrig.session.logformats import LOG_FORMATS
from hilrig.session.netns import PrivateBus, require_private_buses
from hilrig.session.run import (
    BoardInterface,
    PlantFactory,
    RunDescription,
)
from hilrig.table import RigTable
from hilrig.wire.node import BoardNode, answer_filters
from hilrig.wire.transport import socketcan_socket

if TYPE_CHECKING:
    from hilrig.observe.sinks import TraceSink
    from hilrig.observe.tracer import Tracer


@dataclass(frozen=True)
class Rider:
    """Another board on a robot's bus (the head module on the snake): its firmware, table, EDS
    and plant (made from (params, seed) like a session's), started and stepped with the joints."""

    node_id: int
    table: RigTable
    eds: Path
    executable: Path
    plant: PlantFactory
    params: Any = None


@dataclass
class HilSession:
    """What a running session holds; `close()` ends it early (the context manager does it too)."""

    run: RunDescription
    rig: Rig | None  # None: open_session(with_rig=False), or a robot
    node: BoardNode  # a robot's: its first module's
    firmware: Firmware | None  # a robot's: its first module's (all in `robot.firmware`)
    tracer: Tracer | None
    private_bus: PrivateBus | None
    recorder: RecorderProcess | None
    _stack: contextlib.ExitStack = field(repr=False)
    robot: Robot | None = None

    @property
    def out_dir(self) -> Path:
        return self.run.out_dir

    @property
    def bus_log(self) -> Path:
        return bus_log_path(self.run)

    @property
    def trace_path(self) -> Path | None:
        return self.run.out_dir / "trace.rrd" if self.run.trace.trace is True else None

    def evidence(self) -> str:
        """'trace: ..., bus log: ..., firmware log: ...': where to look when something failed."""
        parts = []
        if self.trace_path is not None:
            parts.append(f"trace: {self.trace_path}")
        if self.run.trace.record:
            parts.append(f"bus log: {self.bus_log}")
        if self.robot is not None:
            logs = [f.log_path.name for f in self.robot.firmware if f is not None]
            parts.append(f"firmware logs: {self.out_dir}/{{{','.join(logs)}}}")
        elif self.firmware is not None:
            parts.append(f"firmware log: {self.firmware.log_path}")
        return ", ".join(parts)

    def close(self) -> None:
        self._stack.close()


def _tracer(run: RunDescription, table: RigTable, blueprint: str | None = "overview") -> Tracer | None:
    trace = run.trace
    if trace.trace is False:
        return None
    from hilrig.observe.tracer import Tracer  # rerun is slow to import: only when tracing

    clock = "wall" if run.rig.timing is TimingMode.REALTIME else "simulation"
    sinks: list[TraceSink]
    if trace.trace is True:
        if trace.live:
            from hilrig.observe.sinks import TraceSink

            sinks = [TraceSink.rrd(trace.out_dir / "trace.rrd"), *trace.live]
        else:
            return Tracer.for_scenario(trace.out_dir, table, clock=clock, blueprint=blueprint)
    else:
        sinks = list(trace.trace)
    return Tracer(sinks, table, clock=clock, recording_name=trace.out_dir.name, blueprint=blueprint)


def _module_rig(
    bus: can.BusABC,
    run: RunDescription,
    run_table: RigTable,
    firmware: Firmware | None,
    /,
    **module: Any,
) -> Rig:
    """A Rig of the run: its period (`run_table`'s default: one period for a whole robot),
    timeouts and timing from the run's rig layer; `module` (node_id, eds, plant, tracer, a
    rider's own table...) what differs per module."""
    rig = run.rig
    module.setdefault("table", run_table)
    return Rig(
        bus,
        period_us=rig.cycle_us(run_table),
        liveness=firmware.check if firmware is not None else None,
        activity=firmware.activity if firmware is not None else None,
        boot_timeout_s=run.firmware.boot_timeout_s,
        tpdo_timeout_s=rig.tpdo_timeout_s,
        sdo_timeout_s=rig.sdo_timeout_s,
        **module,
    )


def open_session(
    run: RunDescription,
    *,
    table: RigTable | None = None,
    before_start: Callable[[Rig], None] | None = None,
    private_bus: PrivateBus | None = None,
    start: bool = True,
    with_rig: bool = True,
) -> HilSession:
    """Open a session of `run` (see the module doc); the caller closes it (`HilSession.close`).
    `before_start` sees the rig before it talks to the node. `private_bus`: run on this private
    bus (the caller's, e.g. a test's that also sends frames of its own) instead of a new one.
    `start`: bring the node up (Rig.start) before handing the session over. `with_rig`: False
    is no Rig, only the node (`HilSession.node`: canopen for SDO/NMT and the frame link), for a
    program that puts the engine's driver on it itself (the soak: no plant, no trace)."""
    table = table if table is not None else RigTable.load()
    if run.robot is not None:
        if run.bus.bitrate is not None:
            raise ValueError(
                "bitrate= times one node's bus; a robot's bit rate is computed from its schedule "
                "(`hilrig.apps.robot_bus.robot_bitrate`)"
            )
        return _open_robot(run, table, private_bus, start)
    out = run.out_dir
    out.mkdir(parents=True, exist_ok=True)
    node_id = run.node_id(table)
    board = run.bus.board
    stack = contextlib.ExitStack()
    try:
        recorder: RecorderProcess | None = None
        firmware: Firmware | None = None
        if board is None:
            private_bus, launcher = _launcher(stack, run, private_bus)
            recorder = _recorder(stack, launcher, run)
            log_path = out / "firmware.log"
            firmware = _start_firmware(
                stack, launcher, run, table, node_id, log_path, run.firmware.params_file
            )
        # The tracer before the rig's bus: importing rerun takes seconds (minutes on a loaded
        # emulated VM), and a bus opened before it would queue every heartbeat meanwhile for
        # canopen to wade through before the first SDO answer.
        tracer = _tracer(run, table, run.trace.blueprint)
        if tracer is not None:
            stack.callback(tracer.close)
        if private_bus is not None:
            bus = private_bus.open()
        elif board is not None:
            bus = board.open()
        else:
            bus = BoardInterface("socketcan", run.bus.host_channel or "").open()
        stack.callback(bus.shutdown)
        board_logger = None
        if board is not None and run.trace.record:
            board_logger = _record_board(stack, bus, board, bus_log_path(run))
        if not with_rig:
            node = BoardNode(bus, node_id, run.rig.eds, table, sdo_timeout_s=run.rig.sdo_timeout_s)
            stack.callback(node.close)
            return HilSession(run, None, node, firmware, tracer, private_bus, recorder, stack)
        rig = _module_rig(
            bus,
            run,
            table,
            firmware,
            node_id=node_id,
            eds=run.rig.eds,
            plant=run.rig.plant(run.rig.params, run.rig.seed),
            tracer=tracer,
            mode=run.rig.timing,
            physics=run.rig.physics,
            bitrate=run.bus.timed_bitrate(table),
        )
        stack.callback(rig.close)
        if board_logger is not None:
            assert rig.node.network.notifier is not None  # BoardNode connected the network
            rig.node.network.notifier.add_listener(board_logger)
        if before_start is not None:
            before_start(rig)
        if start:
            rig.start()
    except BaseException:
        stack.close()
        raise
    return HilSession(run, rig, rig.node, firmware, tracer, private_bus, recorder, stack)


def _open_robot(
    run: RunDescription, table: RigTable, private_bus: PrivateBus | None, start: bool
) -> HilSession:
    """The robot variant of `open_session`: N firmware processes on one private bus, one bus
    handle, node and rig per module, one chain, one tracer with a child per module."""
    assert run.robot is not None
    node_ids = module_ids(run.robot.modules)
    # A repeated id, a rider's too, is refused before anything starts.
    module_ids([*node_ids, *(rider.node_id for rider in run.robot.riders)])
    if run.bus.board is not None or run.rig.timing is not TimingMode.LOCKSTEP:
        raise ValueError("a robot session runs its own firmware modules in lockstep (no board=, no realtime)")
    from hilrig.plants.chain import ChainPhysics  # MuJoCo: only for robots

    out = run.out_dir
    out.mkdir(parents=True, exist_ok=True)
    stack = contextlib.ExitStack()
    try:
        chain = ChainPhysics(len(node_ids), params=run.rig.params, seed=run.rig.seed)
        chain.mujoco_steps_per_period(run.rig.cycle_us(table) / 1e6)  # a period MuJoCo cannot step: now
        private_bus, launcher = _launcher(stack, run, private_bus)
        recorder = _recorder(stack, launcher, run)
        firmware = [
            _start_firmware(
                stack, launcher, run, table, k, out / f"firmware-{k}.log", out / f"params-{k}.bin"
            )
            for k in node_ids
        ]
        tracer = _tracer(run, table, blueprint=None)
        if tracer is not None:
            stack.callback(tracer.close)
            from hilrig.observe.blueprints import robot_blueprint

            tracer.send_blueprint(robot_blueprint(table, node_ids))
        modules: list[Rig] = []
        for k, node_id in enumerate(node_ids):
            if private_bus is not None:
                bus = private_bus.open()
            else:
                bus = BoardInterface("socketcan", launcher.channel).open()
            stack.callback(bus.shutdown)
            # Each module's canopen network wakes for its own node's frames only (kernel
            # filters), not for every module's SDO traffic while they all start side by side.
            bus.set_filters(answer_filters(node_id, bus, emcy_cob_id(node_id)))
            module_tracer = None
            if tracer is not None:
                module_tracer = tracer.module_tracer(node_id)
                stack.callback(module_tracer.close)
            rig = _module_rig(
                bus,
                run,
                table,
                firmware[k],
                node_id=node_id,
                eds=run.rig.eds,
                plant=chain.models[k],  # each with a sensor noise of its own
                tracer=module_tracer,
            )
            stack.callback(rig.close)
            modules.append(rig)
        for rider in run.robot.riders:
            rider_firmware = _start_firmware(
                stack,
                launcher,
                run,
                table,
                rider.node_id,
                out / f"firmware-{rider.node_id}.log",
                out / f"params-{rider.node_id}.bin",
                executable=rider.executable,
            )
            firmware.append(rider_firmware)
            modules.append(
                _rider_rig(stack, run, table, rider, rider_firmware, private_bus, launcher, tracer)
            )
        robot = Robot(modules, chain, firmware=firmware, master=run.robot.master)
        if tracer is not None:
            chain_trace = tracer.robot_observer(chain)
            robot.add_observer(chain_trace)
            stack.callback(chain_trace.flush)  # before the tracer closes (the stack unwinds)
        if start:
            robot.start()
    except BaseException:
        stack.close()
        raise
    return HilSession(
        run, None, modules[0].node, firmware[0], tracer, private_bus, recorder, stack, robot=robot
    )


def _rider_rig(
    stack: contextlib.ExitStack,
    run: RunDescription,
    table: RigTable,
    rider: Rider,
    firmware: Firmware,
    private_bus: PrivateBus | None,
    launcher: PrivateBus | _HostChannel,
    tracer: Tracer | None,
) -> Rig:
    """A robot's rider as a module: its own bus handle, node, plant and trace under its root."""
    if private_bus is not None:
        bus = private_bus.open()
    else:
        bus = BoardInterface("socketcan", launcher.channel).open()
    stack.callback(bus.shutdown)
    bus.set_filters(answer_filters(rider.node_id, bus, emcy_cob_id(rider.node_id)))
    module_tracer = None
    if tracer is not None:
        module_tracer = tracer.module_tracer(rider.node_id, rider.table)
        stack.callback(module_tracer.close)
    rig = _module_rig(
        bus,
        run,
        table,
        firmware,
        node_id=rider.node_id,
        eds=rider.eds,
        plant=rider.plant(rider.params, run.rig.seed * 1000 + rider.node_id),
        table=rider.table,
        tracer=module_tracer,
    )
    stack.callback(rig.close)
    return rig


def _launcher(
    stack: contextlib.ExitStack, run: RunDescription, private_bus: PrivateBus | None
) -> tuple[PrivateBus | None, PrivateBus | _HostChannel]:
    """Where the session's processes run: the caller's private bus, the host's interface
    (`host_channel`), or a new private bus (closed with the session)."""
    host_channel = run.bus.host_channel
    if private_bus is None and host_channel is None:
        require_private_buses("a HIL session")
        private_bus = stack.enter_context(PrivateBus())
    launcher = private_bus if private_bus is not None else _HostChannel(host_channel or "")
    return private_bus, launcher


def bus_log_path(run: RunDescription) -> Path:
    """Where the session's bus log goes: out_dir/bus.log, or bus.blf, bus.mf4... by its format."""
    trace = run.trace
    if trace.bus_log_format not in LOG_FORMATS:
        raise ValueError(f"bus log format {trace.bus_log_format!r}: choose one of {', '.join(LOG_FORMATS)}")
    return trace.out_dir / f"bus{trace.bus_log_format}"


def _recorder(
    stack: contextlib.ExitStack, launcher: PrivateBus | _HostChannel, run: RunDescription
) -> RecorderProcess | None:
    """The bus log (out_dir/bus.log) from a recorder process of its own, when `record`."""
    if not run.trace.record:
        return None
    recorder = RecorderProcess(launcher, bus_log_path(run))
    stack.callback(recorder.close)
    return recorder


def _start_firmware(
    stack: contextlib.ExitStack,
    launcher: PrivateBus | _HostChannel,
    run: RunDescription,
    table: RigTable,
    node_id: int,
    log_path: Path,
    params_file: Path | None,
    *,
    executable: Path | None = None,
) -> Firmware:
    """One firmware process of the session, started (stopped with it): its mode and period follow
    the rig's timing (`FirmwareRun.own_period_us`).
    `executable`: another board's firmware (a robot's rider), without the session's extra_args."""
    own_firmware = run.firmware
    platform = baremetal.LINUX
    own = executable is None  # the session's board (its extra_args), not a rider
    if executable is None:
        platform = own_firmware.module_platforms.get(node_id, own_firmware.platform)
        executable = own_firmware.image if platform == baremetal.QEMU_VIRT else own_firmware.executable
    firmware = Firmware(
        launcher,
        node_id=node_id,
        log_path=log_path,
        params_file=params_file,
        extra_args=own_firmware.extra_args if own else (),
        executable=executable,
        mode=run.rig.timing,
        period_us=own_firmware.own_period_us(run.rig, table),
        term_timeout_s=own_firmware.term_timeout_s,
        image_dir=log_path.parent / f"images-{node_id}",
        platform=platform,
    )
    firmware.start()
    stack.callback(firmware.stop)
    return firmware


def _record_board(
    stack: contextlib.ExitStack, bus: can.BusABC, board: BoardInterface, path: Path
) -> can.Listener | None:
    """A real board's bus log: on SocketCAN from a recorder process with a socket of its own (it
    sees every sender). On other interfaces (one handle only: PCAN and friends allow no more)
    the returned logger is to be fed by the notifier that reads the rig's bus (canopen's)."""
    if socketcan_socket(bus) is not None:
        recorder = RecorderProcess(_HostChannel(board.channel), path)
        stack.callback(recorder.close)
        return None
    logging = whole_file_logger(path)
    logger = logging.__enter__()
    stack.callback(lambda: logging.__exit__(None, None, None))
    return logger


class _HostChannel:
    """A launcher for processes on an interface of this host (no namespace)."""

    namespace_file = None  # this host's own network namespace

    def __init__(self, channel: str) -> None:
        self.channel = channel

    def popen(self, argv: list[str], **kwargs: Any) -> Any:
        import subprocess

        return subprocess.Popen(argv, **kwargs)


@contextlib.contextmanager
def hil_session(
    run: RunDescription,
    *,
    table: RigTable | None = None,
    before_start: Callable[[Rig], None] | None = None,
    private_bus: PrivateBus | None = None,
    start: bool = True,
    with_rig: bool = True,
) -> Iterator[HilSession]:
    """`open_session` as a context manager: closed in reverse order however the body ends."""
    session = open_session(
        run, table=table, before_start=before_start, private_bus=private_bus, start=start, with_rig=with_rig
    )
    try:
        yield session
    finally:
        session.close()


__all__ = [
    "BoardInterface",
    "HilSession",
    "PlantFactory",
    "Rider",
    "RunDescription",
    "hil_session",
    "open_session",
]
