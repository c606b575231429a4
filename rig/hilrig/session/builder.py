"""One place that assembles a HIL session: the firmware on a private bus, the bus log, the tracer
and the rig (or, for a real board, the rig on the board's interface with no firmware), opened in
order and closed in reverse on one `contextlib.ExitStack`. Used by the pytest fixtures,
`hilrig sim` / `make run`, the bench and the trace bench::

    with hil_session(SessionConfig(out_dir=Path("out/run"), seed=1)) as session:
        session.rig.set("control_mode", ControlMode.VELOCITY)  # from hilrig.table
        session.rig.run(seconds=1.0)
    # firmware stopped (SIGTERM, its stop line in out/run/firmware.log), out/run/bus.log and
    # out/run/trace.rrd whole

A real board: `SessionConfig(out_dir=..., board=BoardInterface("socketcan", "can0"), mode="realtime")`.

A robot: `SessionConfig(out_dir=..., modules=8)` starts the firmware 8 times (node ids 1..8, or a
list), each with its own log (firmware-<id>.log) and parameter file (params-<id>.bin), and hands
over `session.robot` (`hilrig.engine.robot.Robot`): one bus, one SYNC, the chain's mechanics from MuJoCo,
each module's trace under /modules/<id>.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import can

from boardproto.cia301 import emcy_cob_id
from hilrig.engine.rig import DEFAULT_EDS_PATH, Rig, TimingMode
from hilrig.engine.robot import MasterHeartbeat, Robot, module_ids
from hilrig.errors import BusUnavailableError
from hilrig.plants import default_plant
from hilrig.plants.interface import Plant
from hilrig.session import baremetal
from hilrig.session.buslog import RecorderProcess, whole_file_logger
from hilrig.session.firmware import DEFAULT_EXECUTABLE, Firmware
from hilrig.session.logformats import LOG_FORMATS
from hilrig.session.netns import PrivateBus, require_private_buses
from hilrig.table import RigTable
from hilrig.wire.node import BoardNode, answer_filters
from hilrig.wire.transport import socketcan_socket

if TYPE_CHECKING:
    from hilrig.observe.sinks import TraceSink
    from hilrig.observe.tracer import Tracer

FIRMWARE_MODE = {TimingMode.LOCKSTEP: "lockstep", TimingMode.REALTIME: "free"}
"""The firmware's --mode for each rig timing mode."""
BOOT_TIMEOUT_S = 60.0
"""Hang guard for start-up inside the software-emulated VM (ASan build), not a timing check."""


@dataclass(frozen=True)
class BoardInterface:
    """A real board's bus, as python-can opens it (interface, channel, bitrate, extra kwargs)."""

    interface: str
    channel: str
    bitrate: int | None = None
    kwargs: dict[str, Any] = field(default_factory=dict)

    def open(self) -> can.BusABC:
        extra = dict(self.kwargs)
        if self.bitrate is not None:
            extra["bitrate"] = self.bitrate
        try:
            return can.Bus(interface=self.interface, channel=self.channel, **extra)
        except (can.CanError, OSError, ValueError, ImportError) as error:
            raise BusUnavailableError(
                f"cannot open {self.interface} channel {self.channel}: {error}"
            ) from error


PlantFactory = Callable[[Any, int], Plant]
"""Makes a session's plant from (SessionConfig.params, SessionConfig.seed): the board's hardware
model (`hilrig.plants.interface.Plant`); `hilrig.plants.default_plant` makes the demo joint."""


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


@dataclass(frozen=True)
class SessionConfig:
    """Everything a session is made of. out_dir: firmware.log, bus.log and trace.rrd go here.
    trace: a trace.rrd in out_dir (True; `live` sinks beside it), these sinks (a sequence of
    `TraceSink`), or none.
    board: a real board (no firmware is started); None: the firmware on a private vcan0.
    firmware_period_us: the firmware's own period (default: the rig's, or 10 ms in real time).
    plant: what makes the plant from `params` (its parameters, None: its defaults) and `seed`
    (its noise); a robot's modules are its chain's (the demo joint's).
    """

    out_dir: Path
    params: Any = None
    seed: int = 0
    plant: PlantFactory = default_plant
    blueprint: str | None = "overview"
    """The dashboard (`dashboards.BLUEPRINTS`) the trace opens with, built for the session's
    table: the board's own ("head" for the head module), None for the viewer's default."""
    node_id: int | None = None
    mode: TimingMode | str = TimingMode.LOCKSTEP
    period_us: int = 1000
    bitrate: int | None = None
    """Lockstep on a bus with this bit rate (`hilrig.engine.bustiming`: what does not fit a
    cycle arrives in a later one); None: the ideal bus, every frame in its cycle. Scenarios
    take the table's ([node] bitrate) by default (`--hil-timed-bus`, `ideal_bus(why)`)."""
    physics: bool = True
    trace: bool | Sequence[TraceSink] = True
    live: Sequence[TraceSink] = ()
    """With trace=True: also stream to these sinks (a viewer) while the run goes."""
    record: bool = True
    bus_log_format: str = ".log"
    """The bus log's format, out_dir/bus<format>: one of `logformats.LOG_FORMATS`."""
    board: BoardInterface | None = None
    executable: Path = DEFAULT_EXECUTABLE
    eds: Path = DEFAULT_EDS_PATH
    params_file: Path | None = None
    extra_args: Sequence[str] = ()
    firmware_period_us: int | None = None
    boot_timeout_s: float = BOOT_TIMEOUT_S
    sdo_timeout_s: float = 5.0
    tpdo_timeout_s: float = 5.0
    start: bool = True
    """Bring the node up (Rig.start) before handing the session over."""
    rig: bool = True
    """False: no Rig, only the node (`HilSession.node`: canopen for SDO/NMT and the frame link),
    for a program that puts the engine's driver on it itself (the soak: no plant, no trace)."""
    host_channel: str | None = None
    """Run the firmware on this interface of the host as it is, instead of a private vcan0."""
    firmware_term_timeout_s: float = 5.0
    modules: int | Sequence[int] | None = None
    """A robot: this many modules (node ids 1..N) or these node ids, on one private bus (lockstep,
    the firmware started by the session; `node_id`, `params_file` and `board` do not apply)."""
    master: MasterHeartbeat | None = field(default_factory=MasterHeartbeat)
    """A robot's master heartbeat (None: the rig sends none and the modules watch nothing)."""
    riders: Sequence[Rider] = ()
    """A robot's other boards on its bus, after its joints (`Robot.riders`)."""
    firmware_platform: str = baremetal.LINUX
    """Where the board's firmware runs (`baremetal.FIRMWARE_PLATFORMS`): the Linux process, or
    `baremetal_image` under qemu-system-arm ("qemu-virt")."""
    module_platforms: Mapping[int, str] = field(default_factory=dict)
    """A robot's modules by node id that run on another platform than `firmware_platform`."""
    baremetal_image: Path = field(default_factory=lambda: baremetal.default_image(baremetal.QEMU_VIRT))
    """The image the "qemu-virt" platform runs (the demo joint's: `make baremetal`)."""


@dataclass
class HilSession:
    """What a running session holds; `close()` ends it early (the context manager does it too)."""

    config: SessionConfig
    rig: Rig | None  # None: SessionConfig(rig=False), or a robot
    node: BoardNode  # a robot's: its first module's
    firmware: Firmware | None  # a robot's: its first module's (all in `robot.firmware`)
    tracer: Tracer | None
    private_bus: PrivateBus | None
    recorder: RecorderProcess | None
    _stack: contextlib.ExitStack = field(repr=False)
    robot: Robot | None = None

    @property
    def out_dir(self) -> Path:
        return self.config.out_dir

    @property
    def bus_log(self) -> Path:
        return bus_log_path(self.config)

    @property
    def trace_path(self) -> Path | None:
        return self.config.out_dir / "trace.rrd" if self.config.trace is True else None

    def evidence(self) -> str:
        """'trace: ..., bus log: ..., firmware log: ...': where to look when something failed."""
        parts = []
        if self.trace_path is not None:
            parts.append(f"trace: {self.trace_path}")
        if self.config.record:
            parts.append(f"bus log: {self.bus_log}")
        if self.robot is not None:
            logs = [f.log_path.name for f in self.robot.firmware if f is not None]
            parts.append(f"firmware logs: {self.out_dir}/{{{','.join(logs)}}}")
        elif self.firmware is not None:
            parts.append(f"firmware log: {self.firmware.log_path}")
        return ", ".join(parts)

    def close(self) -> None:
        self._stack.close()


def _tracer(config: SessionConfig, table: RigTable, blueprint: str | None = "overview") -> Tracer | None:
    if config.trace is False:
        return None
    from hilrig.observe.tracer import Tracer  # rerun is slow to import: only when tracing

    clock = "wall" if TimingMode(config.mode) is TimingMode.REALTIME else "simulation"
    sinks: list[TraceSink]
    if config.trace is True:
        if config.live:
            from hilrig.observe.sinks import TraceSink

            sinks = [TraceSink.rrd(config.out_dir / "trace.rrd"), *config.live]
        else:
            return Tracer.for_scenario(config.out_dir, table, clock=clock, blueprint=blueprint)
    else:
        sinks = list(config.trace)
    return Tracer(sinks, table, clock=clock, recording_name=config.out_dir.name, blueprint=blueprint)


def open_session(
    config: SessionConfig,
    *,
    table: RigTable | None = None,
    before_start: Callable[[Rig], None] | None = None,
    private_bus: PrivateBus | None = None,
) -> HilSession:
    """Open a session (see the module doc); the caller closes it (`HilSession.close`).
    `before_start` sees the rig before it talks to the node. `private_bus`: run on this private
    bus (the caller's, e.g. a test's that also sends frames of its own) instead of a new one."""
    table = table if table is not None else RigTable.load()
    if config.modules is not None:
        if config.bitrate is not None:
            raise ValueError(
                "bitrate= times one node's bus; a robot's bit rate is computed from its schedule "
                "(`hilrig.apps.robot_bus.robot_bitrate`)"
            )
        return _open_robot(config, table, private_bus)
    mode = TimingMode(config.mode)
    out = config.out_dir
    out.mkdir(parents=True, exist_ok=True)
    node_id = config.node_id if config.node_id is not None else table.board.node.default_node_id
    stack = contextlib.ExitStack()
    try:
        recorder: RecorderProcess | None = None
        firmware: Firmware | None = None
        if config.board is None:
            private_bus, launcher = _launcher(stack, config, private_bus)
            recorder = _recorder(stack, launcher, config)
            log_path = out / "firmware.log"
            firmware = _start_firmware(stack, launcher, config, node_id, log_path, config.params_file)
        # The tracer before the rig's bus: importing rerun takes seconds (minutes on a loaded
        # emulated VM), and a bus opened before it would queue every heartbeat meanwhile for
        # canopen to wade through before the first SDO answer.
        tracer = _tracer(config, table, config.blueprint)
        if tracer is not None:
            stack.callback(tracer.close)
        if private_bus is not None:
            bus = private_bus.open()
        elif config.board is not None:
            bus = config.board.open()
        else:
            bus = BoardInterface("socketcan", config.host_channel or "").open()
        stack.callback(bus.shutdown)
        board_logger = None
        if config.board is not None and config.record:
            board_logger = _record_board(stack, bus, config.board, bus_log_path(config))
        if not config.rig:
            node = BoardNode(bus, node_id, config.eds, table, sdo_timeout_s=config.sdo_timeout_s)
            stack.callback(node.close)
            return HilSession(config, None, node, firmware, tracer, private_bus, recorder, stack)
        rig = Rig(
            bus,
            node_id=node_id,
            eds=config.eds,
            plant=config.plant(config.params, config.seed),
            period_us=config.period_us,
            table=table,
            liveness=firmware.check if firmware is not None else None,
            activity=firmware.activity if firmware is not None else None,
            boot_timeout_s=config.boot_timeout_s,
            tpdo_timeout_s=config.tpdo_timeout_s,
            sdo_timeout_s=config.sdo_timeout_s,
            tracer=tracer,
            mode=mode,
            physics=config.physics,
            bitrate=config.bitrate,
        )
        stack.callback(rig.close)
        if board_logger is not None:
            assert rig.node.network.notifier is not None  # BoardNode connected the network
            rig.node.network.notifier.add_listener(board_logger)
        if before_start is not None:
            before_start(rig)
        if config.start:
            rig.start()
    except BaseException:
        stack.close()
        raise
    return HilSession(config, rig, rig.node, firmware, tracer, private_bus, recorder, stack)


def _open_robot(config: SessionConfig, table: RigTable, private_bus: PrivateBus | None) -> HilSession:
    """The robot variant of `open_session`: N firmware processes on one private bus, one bus
    handle, node and rig per module, one chain, one tracer with a child per module."""
    assert config.modules is not None
    node_ids = module_ids(config.modules)
    # A repeated id, a rider's too, is refused before anything starts.
    module_ids([*node_ids, *(rider.node_id for rider in config.riders)])
    if config.board is not None or TimingMode(config.mode) is not TimingMode.LOCKSTEP:
        raise ValueError("a robot session runs its own firmware modules in lockstep (no board=, no realtime)")
    from hilrig.plants.chain import ChainPhysics  # MuJoCo: only for robots

    out = config.out_dir
    out.mkdir(parents=True, exist_ok=True)
    stack = contextlib.ExitStack()
    try:
        chain = ChainPhysics(len(node_ids), params=config.params, seed=config.seed)
        chain.mujoco_steps_per_period(config.period_us / 1e6)  # a period MuJoCo cannot step: now
        private_bus, launcher = _launcher(stack, config, private_bus)
        recorder = _recorder(stack, launcher, config)
        firmware = [
            _start_firmware(stack, launcher, config, k, out / f"firmware-{k}.log", out / f"params-{k}.bin")
            for k in node_ids
        ]
        tracer = _tracer(config, table, blueprint=None)
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
            rig = Rig(
                bus,
                node_id=node_id,
                eds=config.eds,
                plant=chain.models[k],  # each with a sensor noise of its own
                period_us=config.period_us,
                table=table,
                liveness=firmware[k].check,
                activity=firmware[k].activity,
                boot_timeout_s=config.boot_timeout_s,
                tpdo_timeout_s=config.tpdo_timeout_s,
                sdo_timeout_s=config.sdo_timeout_s,
                tracer=module_tracer,
            )
            stack.callback(rig.close)
            modules.append(rig)
        for rider in config.riders:
            rider_firmware = _start_firmware(
                stack,
                launcher,
                config,
                rider.node_id,
                out / f"firmware-{rider.node_id}.log",
                out / f"params-{rider.node_id}.bin",
                executable=rider.executable,
            )
            firmware.append(rider_firmware)
            modules.append(_rider_rig(stack, config, rider, rider_firmware, private_bus, launcher, tracer))
        robot = Robot(modules, chain, firmware=firmware, master=config.master)
        if tracer is not None:
            chain_trace = tracer.robot_observer(chain)
            robot.add_observer(chain_trace)
            stack.callback(chain_trace.flush)  # before the tracer closes (the stack unwinds)
        if config.start:
            robot.start()
    except BaseException:
        stack.close()
        raise
    return HilSession(
        config, None, modules[0].node, firmware[0], tracer, private_bus, recorder, stack, robot=robot
    )


def _rider_rig(
    stack: contextlib.ExitStack,
    config: SessionConfig,
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
    rig = Rig(
        bus,
        node_id=rider.node_id,
        eds=rider.eds,
        plant=rider.plant(rider.params, config.seed * 1000 + rider.node_id),
        period_us=config.period_us,
        table=rider.table,
        liveness=firmware.check,
        activity=firmware.activity,
        boot_timeout_s=config.boot_timeout_s,
        tpdo_timeout_s=config.tpdo_timeout_s,
        sdo_timeout_s=config.sdo_timeout_s,
        tracer=module_tracer,
    )
    stack.callback(rig.close)
    return rig


def _launcher(
    stack: contextlib.ExitStack, config: SessionConfig, private_bus: PrivateBus | None
) -> tuple[PrivateBus | None, PrivateBus | _HostChannel]:
    """Where the session's processes run: the caller's private bus, the host's interface
    (`host_channel`), or a new private bus (closed with the session)."""
    if private_bus is None and config.host_channel is None:
        require_private_buses("a HIL session")
        private_bus = stack.enter_context(PrivateBus())
    launcher = private_bus if private_bus is not None else _HostChannel(config.host_channel or "")
    return private_bus, launcher


def bus_log_path(config: SessionConfig) -> Path:
    """Where the session's bus log goes: out_dir/bus.log, or bus.blf, bus.mf4... by its format."""
    if config.bus_log_format not in LOG_FORMATS:
        raise ValueError(f"bus log format {config.bus_log_format!r}: choose one of {', '.join(LOG_FORMATS)}")
    return config.out_dir / f"bus{config.bus_log_format}"


def _recorder(
    stack: contextlib.ExitStack, launcher: PrivateBus | _HostChannel, config: SessionConfig
) -> RecorderProcess | None:
    """The bus log (out_dir/bus.log) from a recorder process of its own, when `record`."""
    if not config.record:
        return None
    recorder = RecorderProcess(launcher, bus_log_path(config))
    stack.callback(recorder.close)
    return recorder


def _start_firmware(
    stack: contextlib.ExitStack,
    launcher: PrivateBus | _HostChannel,
    config: SessionConfig,
    node_id: int,
    log_path: Path,
    params_file: Path | None,
    *,
    executable: Path | None = None,
) -> Firmware:
    """One firmware process of the session, started (stopped with it): its mode and period follow
    the rig's timing (lockstep: the rig's period; real time: its own 10 ms unless given).
    `executable`: another board's firmware (a robot's rider), without the session's extra_args."""
    mode = TimingMode(config.mode)
    platform = baremetal.LINUX
    own = executable is None  # the session's board (its extra_args), not a rider
    if executable is None:
        platform = config.module_platforms.get(node_id, config.firmware_platform)
        executable = config.baremetal_image if platform == baremetal.QEMU_VIRT else config.executable
    firmware = Firmware(
        launcher,
        node_id=node_id,
        log_path=log_path,
        params_file=params_file,
        extra_args=config.extra_args if own else (),
        executable=executable,
        mode=FIRMWARE_MODE[mode],
        period_us=config.firmware_period_us or (config.period_us if mode is TimingMode.LOCKSTEP else 10_000),
        term_timeout_s=config.firmware_term_timeout_s,
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
    config: SessionConfig,
    *,
    table: RigTable | None = None,
    before_start: Callable[[Rig], None] | None = None,
    private_bus: PrivateBus | None = None,
) -> Iterator[HilSession]:
    """`open_session` as a context manager: closed in reverse order however the body ends."""
    session = open_session(config, table=table, before_start=before_start, private_bus=private_bus)
    try:
        yield session
    finally:
        session.close()


__all__ = ["BoardInterface", "HilSession", "Rider", "SessionConfig", "hil_session", "open_session"]
