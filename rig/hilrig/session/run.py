"""One description of a run: what bus, which firmware how, what the rig simulates, where the
evidence goes. Frozen and layered, passed whole to the builder (`hilrig.session.builder`)::

    run = RunDescription(TraceRun(Path("out/run")), rig=RigRun(seed=1))
    with hil_session(run) as session:
        session.rig.run(seconds=1.0)

Its defaults and valid ranges come from one home each: the control period's from the table's
[node] block (period_us, period_us_min..period_us_max, also compiled into the firmware's header),
the rest from the layer that uses them. A command line builds it with one function
(`RunDescription.add_arguments` + `RunDescription.from_arguments`), the pytest plugin with
`RunDescription.from_pytest`, by the same options (`RUN_OPTIONS`), checks and error texts.

A run option is one `RunOption` here (its flag, the field it sets, its check); the layer field it
sets is read by the one place that uses it.
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from hilrig import resources
from hilrig.arguments import (
    ArgKind,
    existing_file,
    kind,
    node_id,
    positive_float,
    positive_int,
    sniff_eds,
    sniff_executable,
)
from hilrig.engine.timing import TimingMode
from hilrig.errors import BusUnavailableError, ConfigurationError
from hilrig.session import baremetal
from hilrig.table import RigTable

if TYPE_CHECKING:
    import can

    from hilrig.engine.robot import MasterHeartbeat
    from hilrig.observe.sinks import TraceSink
    from hilrig.plants.interface import Plant

BOOT_TIMEOUT_S = 60.0
"""Hang guard for start-up inside the software-emulated VM (ASan build), not a timing check."""
REALTIME_FIRMWARE_PERIOD_US = 10_000
"""A free-running firmware's own period when the run names none (its timer on a loaded host)."""

PlantFactory = Callable[[Any, int], "Plant"]
"""Makes a run's plant from (RigRun.params, RigRun.seed): the board's hardware model
(`hilrig.plants.interface.Plant`); `hilrig.plants.default_plant` makes the demo joint."""


def default_plant(params: Any, seed: int) -> Plant:
    """The demo joint (`hilrig.plants.default_plant`), imported when a run makes its plant."""
    from hilrig import plants

    return plants.default_plant(params, seed)


def _master_heartbeat() -> MasterHeartbeat:
    from hilrig.engine.robot import MasterHeartbeat

    return MasterHeartbeat()


class RunOptionError(ConfigurationError):
    """A run option out of its range (the message names the option and the range)."""


@dataclass(frozen=True)
class BoardInterface:
    """A real board's bus, as python-can opens it (interface, channel, bitrate, extra kwargs)."""

    interface: str
    channel: str
    bitrate: int | None = None
    kwargs: dict[str, Any] = field(default_factory=dict)

    def open(self) -> can.BusABC:
        import can  # python-can: only when a bus is opened

        extra = dict(self.kwargs)
        if self.bitrate is not None:
            extra["bitrate"] = self.bitrate
        try:
            return can.Bus(interface=self.interface, channel=self.channel, **extra)
        except (can.CanError, OSError, ValueError, ImportError) as error:
            raise BusUnavailableError(
                f"cannot open {self.interface} channel {self.channel}: {error}"
            ) from error


@dataclass(frozen=True)
class BusRun:
    """Where the run's frames go. board: a real board's bus (no firmware is started); else the
    firmware's private vcan0, or `host_channel` (an interface of this host as it is).
    bitrate: lockstep on a bus of this bit rate (`hilrig.engine.bustiming`: what does not fit a
    cycle arrives in a later one), "table" for the table's [node] bitrate, None: the ideal bus."""

    board: BoardInterface | None = None
    host_channel: str | None = None
    bitrate: int | Literal["table"] | None = None

    def timed_bitrate(self, table: RigTable) -> int | None:
        return table.board.node.bitrate if self.bitrate == "table" else self.bitrate


@dataclass(frozen=True)
class FirmwareRun:
    """The firmware the run starts (none on a real board's bus). Its timing mode is the rig's
    (`RigRun.timing`: lockstep, or free-running beside a real-time rig), its period the rig's in
    lockstep and its own (`period_us`, default `REALTIME_FIRMWARE_PERIOD_US`) in real time.
    platform: `baremetal.FIRMWARE_PLATFORMS` (the Linux process, or `image` under qemu)."""

    executable: Path = resources.DEFAULT_FIRMWARE
    platform: str = baremetal.LINUX
    image: Path = field(default_factory=lambda: baremetal.default_image(baremetal.QEMU_VIRT))
    """The image the "qemu-virt" platform runs (the demo joint's: `make baremetal`)."""
    node_id: int | None = None
    """None: the table's default_node_id."""
    period_us: int | None = None
    params_file: Path | None = None
    extra_args: Sequence[str] = ()
    boot_timeout_s: float = BOOT_TIMEOUT_S
    term_timeout_s: float = 5.0
    module_platforms: Mapping[int, str] = field(default_factory=dict)
    """A robot's modules by node id that run on another platform than `platform`."""

    def own_period_us(self, rig: RigRun, table: RigTable) -> int:
        """The firmware's --period-us in this run."""
        if rig.timing is TimingMode.LOCKSTEP:
            return rig.cycle_us(table)
        return self.period_us if self.period_us is not None else REALTIME_FIRMWARE_PERIOD_US


@dataclass(frozen=True)
class RigRun:
    """What the rig does. timing: lockstep (it produces SYNC, exact simulation time) or real
    time (its own wall-clock tick of `period_us` beside a free-running node); period_us: None is
    the table's [node] period_us. plant: made from (params, seed); physics: False only in real
    time (observe and command a real board)."""

    timing: TimingMode = TimingMode.LOCKSTEP
    period_us: int | None = None
    plant: PlantFactory = default_plant
    params: Any = None
    seed: int = 0
    physics: bool = True
    eds: Path = resources.DEFAULT_EDS
    sdo_timeout_s: float = 5.0
    tpdo_timeout_s: float = 5.0

    def cycle_us(self, table: RigTable) -> int:
        """The rig's control period in this run."""
        return self.period_us if self.period_us is not None else table.board.node.period_us


@dataclass(frozen=True)
class TraceRun:
    """The run's evidence in out_dir: trace.rrd (trace=True; `live` sinks beside it), these sinks
    (a sequence of `TraceSink`) or none; the bus log (`record`) as out_dir/bus<bus_log_format>."""

    out_dir: Path
    trace: bool | Sequence[TraceSink] = True
    live: Sequence[TraceSink] = ()
    record: bool = True
    bus_log_format: str = ".log"
    """One of `hilrig.session.logformats.LOG_FORMATS`."""
    blueprint: str | None = "overview"
    """The dashboard (`dashboards.BLUEPRINTS`) the trace opens with, built for the run's table."""


@dataclass(frozen=True)
class RobotRun:
    """A robot: this many modules (node ids 1..N) or these node ids on one private bus, in
    lockstep; a master heartbeat (None: none); other boards on the bus after the joints."""

    modules: int | Sequence[int]
    master: MasterHeartbeat | None = field(default_factory=_master_heartbeat)
    riders: Sequence[Any] = ()
    """`hilrig.session.builder.Rider`s."""


@dataclass(frozen=True)
class RunDescription:
    """A whole run (see the module doc); `replace(rig=..., ...)` for a variant."""

    trace: TraceRun
    bus: BusRun = field(default_factory=BusRun)
    firmware: FirmwareRun = field(default_factory=FirmwareRun)
    rig: RigRun = field(default_factory=RigRun)
    robot: RobotRun | None = None

    @property
    def out_dir(self) -> Path:
        return self.trace.out_dir

    def replace(self, **layers: Any) -> RunDescription:
        return dataclasses.replace(self, **layers)

    def node_id(self, table: RigTable) -> int:
        return (
            self.firmware.node_id if self.firmware.node_id is not None else table.board.node.default_node_id
        )

    @staticmethod
    def add_arguments(parser: argparse.ArgumentParser | Any, *dests: str, **defaults: Any) -> None:
        """Add the run options named by `dests` (`RUN_OPTIONS`' dests; none: all) to an argparse
        parser or group; `defaults` replace a layer's default for this command (seed=1)."""
        for option in _chosen(dests):
            default = defaults.get(option.dest, option.default)
            shown = "" if default is None else f" (default: {default})"
            parser.add_argument(
                *option.flags,
                dest=option.dest,
                type=option.type,
                default=default,
                metavar=option.metavar,
                help=option.help + shown,
            )

    @classmethod
    def from_arguments(
        cls, args: argparse.Namespace, table: RigTable, base: RunDescription | None = None
    ) -> RunDescription:
        """`base` (default: a run into args.out, or out/) with every run option the command line has
        set, checked against `table`; `RunOptionError` names the option and its valid range."""
        run = base if base is not None else cls(TraceRun(getattr(args, "out", None) or Path("out")))
        given = {
            option.dest: getattr(args, option.dest) for option in RUN_OPTIONS if hasattr(args, option.dest)
        }
        return run.with_options(given, table)

    @classmethod
    def from_pytest(cls, config: Any, base: RunDescription, table: RigTable) -> RunDescription:
        """`base` with the run options given to pytest (`--hil-period-us`...: `pytest_options`),
        by the same checks and error texts as the command line's."""
        given = {}
        for option in RUN_OPTIONS:
            value = config.getoption(f"hil_{option.dest}", None) if option.pytest else None
            if value is not None:
                given[option.dest] = value
        return base.with_options(given, table)

    @staticmethod
    def pytest_options() -> tuple[tuple[str, dict[str, Any]], ...]:
        """(flag, addoption keywords) of the run options pytest takes too, spelled --hil-..."""
        return tuple(
            (
                "--hil-" + option.flags[-1].removeprefix("--"),
                {
                    "dest": f"hil_{option.dest}",
                    "type": option.type,
                    "default": None,
                    "metavar": option.metavar,
                    "help": option.help + " (lockstep scenarios)",
                },
            )
            for option in RUN_OPTIONS
            if option.pytest
        )

    def with_options(self, given: Mapping[str, Any], table: RigTable) -> RunDescription:
        """This run with `given` (dest -> value; None: the layer's default kept), checked."""
        run = self
        for option in RUN_OPTIONS:
            value = given.get(option.dest)
            if value is None:
                continue
            problem = option.check(value, table) if option.check is not None else None
            if problem is not None:
                raise RunOptionError(f"{option.flags[-1]}: {problem}, got {value}")
            layer_name, field_name = option.target.split(".")
            layer = dataclasses.replace(getattr(run, layer_name), **{field_name: value})
            run = dataclasses.replace(run, **{layer_name: layer})
        return run


@dataclass(frozen=True)
class RunOption:
    """One option of a run: its flags, the layer field it sets ("rig.period_us"), its argument
    type and a check against the table (an error text, or None)."""

    flags: tuple[str, ...]
    dest: str
    target: str
    help: str
    type: Callable[[str], Any]
    metavar: str | None = None
    default: Any = None
    check: Callable[[Any, RigTable], str | None] | None = None
    pytest: bool = False
    """Also a pytest option (--hil-<flag>) that applies to every lockstep scenario."""


@kind(ArgKind("number", out_of_range="x"))
def _integer(text: str) -> int:
    try:
        return int(text, 0)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None


def _period_range(value: int, table: RigTable) -> str | None:
    node = table.board.node
    if node.period_us_min <= value <= node.period_us_max:
        return None
    return (
        f"expected a control period of {node.period_us_min}..{node.period_us_max} us (the table's "
        "[node] period_us_min..period_us_max)"
    )


RUN_OPTIONS: tuple[RunOption, ...] = (
    RunOption(
        ("--period-us",),
        "period_us",
        "rig.period_us",
        "control period in microseconds, the firmware's --period-us; default: the table's [node] period_us",
        positive_int,
        metavar="US",
        check=_period_range,
        pytest=True,
    ),
    RunOption(("--seed",), "seed", "rig.seed", "sensor noise seed", _integer),
    RunOption(
        ("--boot-timeout",),
        "boot_timeout",
        "firmware.boot_timeout_s",
        "seconds the firmware may take to boot and answer (a hang guard; default: the run's, "
        f"{BOOT_TIMEOUT_S:g} s on a private bus)",
        positive_float,
        metavar="S",
        pytest=True,
    ),
    RunOption(
        ("--tpdo-timeout",),
        "tpdo_timeout",
        "rig.tpdo_timeout_s",
        "seconds of wall time the rig waits for a TPDO due at a SYNC before it judges the node (a hang "
        "guard: lockstep verdicts never depend on it; default: the run's)",
        positive_float,
        metavar="S",
        pytest=True,
    ),
    RunOption(
        ("-n", "--node-id"),
        "node_id",
        "firmware.node_id",
        "CANopen node id of the firmware, 1..127, decimal or 0x hex; default: the table's [node] "
        "default_node_id",
        node_id,
    ),
    RunOption(
        ("--firmware",),
        "firmware",
        "firmware.executable",
        "the firmware executable; default: build/bin/joint-firmware of the checkout, or of the working "
        "directory when hilrig is installed",
        existing_file("firmware", resources.FIRMWARE_HINT, sniff=sniff_executable),
    ),
    RunOption(
        ("--eds",),
        "eds",
        "rig.eds",
        "the board's EDS; default: the table's (build/protocol/board.eds in a checkout)",
        existing_file("EDS", resources.EDS_HINT, sniff=sniff_eds),
    ),
)
"""The run options, in --help's order."""


def _chosen(dests: Sequence[str]) -> tuple[RunOption, ...]:
    known = {option.dest: option for option in RUN_OPTIONS}
    unknown = [dest for dest in dests if dest not in known]
    if unknown:
        raise ValueError(f"no run option {', '.join(unknown)}: choose from {', '.join(known)}")
    return tuple(known[dest] for dest in dests) if dests else RUN_OPTIONS


__all__ = [
    "BOOT_TIMEOUT_S",
    "RUN_OPTIONS",
    "BoardInterface",
    "BusRun",
    "FirmwareRun",
    "PlantFactory",
    "RigRun",
    "RobotRun",
    "RunDescription",
    "RunOption",
    "RunOptionError",
    "TraceRun",
]
