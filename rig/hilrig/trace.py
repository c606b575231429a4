"""Tracing to Rerun: every field the rig receives or sends, every cycle, next to the physics' truth.

    tracer = Tracer(TraceSink.rrd(scenario_dir / "trace.rrd"), table, blueprint="overview")
    with Rig(bus, params=params, tracer=tracer) as rig:
        rig.run(seconds=1.0)
    tracer.close()                                   # flushes; the .rrd is complete after this
    open_trace(scenario_dir / "trace.rrd", blueprint="tuning")   # native viewer, or web=True

Entity paths mirror the data (dashboards/ builds its views on exactly these):

    /fields/<kind>s/<name>   board fields by kind: sensors, virtual_sensors, modules, actuators,
                             commands, parameters; received in TPDOs, or sent by the rig (RPDO
                             commands every cycle they go out, SDO writes when made)
    /hil/inputs/<name>       raw sensor values the rig sent (RPDO1), /hil/outputs/<name> raw
                             actuator values the node sent (motor_duty, led_pattern)
    /truth/<quantity>        the plant's ground truth (JointState attributes, unit in the name),
                             plus spring_stiffness_nm_per_rad from the plant parameters
    /bus/frames/<PDO>        frames of that PDO's COB-ID in each cycle (TPDO5: 1 every 10th),
                             /bus/per_cycle/{tpdos,rpdos} their sums per direction
    /events/nmt, /events/emcy, /events/sdo, /events/bus    text log entries with a level
    <field or HIL path>/label  for a field whose values have names in board.toml (control_mode,
                             fault_flags, led_pattern): a text entry at each change of value,
                             "control_mode = velocity", "fault_flags = motor_encoder_stale|..."

Every scalar entity carries a static `SeriesLines` name with its unit ("motor_velocity [rad/s]").
Timelines: `cycle` (sequence) and `sim_time` (duration, exact cycle * period) in lockstep; in
real-time mode (`clock="wall"`) `wall_time` (timestamp) replaces `sim_time`.

Off the hot path: as a `RigObserver` the tracer follows the rig's `History` (`on_history`), which
already keeps every PDO's values per cycle, so a traced cycle costs a count and no Rerun call.
Every `batch_cycles` cycles (and, for a live viewer, at least once a second) the span since the
last batch (two `History.mark`s) goes to a background thread that turns each PDO's rows into one
numpy array and sends the series over the same cycles as one Arrow record batch, which Rerun
splits into one chunk per entity. Rows given by `log_cycle` (a replayed log) are pivoted the same
way. Nothing is ever dropped and the lockstep loop never waits for
Rerun (`make bench` measures a traced Rig against an untraced one). `import rerun` is slow in the
emulated VM, so it happens only when a Tracer is made.
"""

from __future__ import annotations

import contextlib
import enum
import functools
import itertools
import os
import queue
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, Self
from urllib.parse import quote

import numpy as np

from boardproto import Field, IoDirection, Kind
from boardproto.cia301 import NmtState
from boardproto.table import BitSet, ValueEnum
from hilrig import resources
from hilrig.driver import BUS_EVENTS_PATH, CycleResult, History, HistoryMark
from hilrig.errors import RigError
from hilrig.node import EmcyRecord
from hilrig.observers import RigObserver
from hilrig.physics import STATE_FIELDS, JointParams, JointState, state_matrix
from hilrig.robot import ROBOT_EVENTS_PATH, RobotObserver
from hilrig.table import RigTable, unknown_name
from hilrig.transport import PdoDirection, PdoLayout

if TYPE_CHECKING:
    import rerun as rr
    import rerun.blueprint as rrb

    from hilrig.robot import ChainModel, Robot

APPLICATION_ID = "hilrig"
"""Rerun application id of every trace; blueprints are saved for this id."""
CYCLE_TIMELINE = "cycle"
SIM_TIME_TIMELINE = "sim_time"
WALL_TIME_TIMELINE = "wall_time"
DEFAULT_BATCH_CYCLES = 5000
"""Cycles collected before one batch is pivoted and sent (5 s of simulation at 1 kHz). Each
batch has a fixed cost in Rerun per entity whatever its length (a chunk, its schema, its place
in the file's footer), so large batches are what makes a traced run cost little: measured
natively, 33 us of CPU per traced cycle at 500 cycles a batch, 13 us at 5000."""
SETTLE_TIMEOUT_S = 5.0
"""How long `Tracer.settle` (at the rig's start, once its series are named) waits for Rerun to
take what was sent so far; past it the start goes on and the rest is written beside the run."""
LIVE_LATENCY_S = 1.0
"""A live sink (spawned, connected or served viewer) also gets a batch whenever this much wall
time passed since the last one, so what it shows is never more than about a second old."""

Value = float | int
Clock = Literal["simulation", "wall"]

# --- Entity paths (dashboards/ uses these, so views and data cannot drift apart) ------------
FIELDS_ROOT = "/fields"
HIL_INPUTS_ROOT = "/hil/inputs"
HIL_OUTPUTS_ROOT = "/hil/outputs"
TRUTH_ROOT = "/truth"
EVENTS_ROOT = "/events"
NMT_PATH = f"{EVENTS_ROOT}/nmt"
EMCY_PATH = f"{EVENTS_ROOT}/emcy"
LABEL_CHILD = "label"
SDO_PATH = f"{EVENTS_ROOT}/sdo"
MODULES_ROOT = "/modules"
"""A robot's modules each trace under /modules/<node id>: their fields, truth and events."""
BUS_ROOT = "/bus"
"""What the driver exchanged per cycle: /bus/frames/<PDO> (frames of that COB-ID in the cycle),
/bus/per_cycle/{tpdos,rpdos} (their sums per direction); /events/bus says which PDOs the node
uses and when a TPDO is late, missing or malformed. Frame counts are step series with a row
where the count changes and at the last cycle of each batch (a missing frame is a 0 at its
cycle and the count again at the next): the value at any cycle is the latest row at or before
it. Sending one row per cycle of a count that hardly ever changes was a third of what a trace
cost to send and write."""
BUS_FRAMES_ROOT = f"{BUS_ROOT}/frames"
BUS_TPDOS_PER_CYCLE = f"{BUS_ROOT}/per_cycle/tpdos"
BUS_RPDOS_PER_CYCLE = f"{BUS_ROOT}/per_cycle/rpdos"
_BUS_TOTALS = ((BUS_TPDOS_PER_CYCLE, PdoDirection.TPDO), (BUS_RPDOS_PER_CYCLE, PdoDirection.RPDO))
"""The frames per cycle of each direction: the series and the direction it sums."""
ROBOT_ROOT = "/robot"
"""A robot's 3D view: /robot/links/<k> (a capsule moved by the chain's pose of link k),
/robot/ground; its own events (a module lost...) at /events/robot."""
TRUE_SPRING_STIFFNESS = "spring_stiffness_nm_per_rad"
"""Extra truth series: the plant's spring constant, to plot next to spring_constant_estimate.
A parameter: a step series with rows where it changes and at the last cycle of each batch."""

_TRUTH_UNITS = (  # the longest suffix first: "_nm_per_rad" also ends in "_rad"
    ("_rad_s", "rad/s"),
    ("_nm_per_rad", "N*m/rad"),
    ("_rad", "rad"),
    ("_nm", "N*m"),
    ("_a", "A"),
    ("_c", "degC"),
    ("_ohm", "ohm"),
)
TRUTH_QUANTITIES: tuple[str, ...] = (
    *(f.name for f in fields(JointState) if f.name != "time_s"),
    TRUE_SPRING_STIFFNESS,
)


def kind_path(kind: Kind) -> str:
    """'/fields/virtual_sensors' for Kind.VIRTUAL_SENSOR."""
    return f"{FIELDS_ROOT}/{kind.value}s"


def field_path(field: Field) -> str:
    """'/fields/sensors/motor_position'."""
    return f"{kind_path(field.kind)}/{field.name}"


def frames_path(pdo: PdoLayout) -> str:
    """'/bus/frames/TPDO3': frames of this PDO's COB-ID per cycle."""
    return f"{BUS_FRAMES_ROOT}/{pdo.direction.value}{pdo.number}"


def module_root(node_id: int) -> str:
    """'/modules/3': where module 3 of a robot traces (prefix of all its entity paths)."""
    return f"{MODULES_ROOT}/{node_id}"


def link_path(index: int) -> str:
    """'/robot/links/0' for the chain's first link."""
    return f"{ROBOT_ROOT}/links/{index}"


def truth_path(quantity: str) -> str:
    """'/truth/load_velocity_rad_s'; the name is checked against the JointState attributes."""
    if quantity not in TRUTH_QUANTITIES:
        raise unknown_name("ground-truth quantity", quantity, TRUTH_QUANTITIES)
    return f"{TRUTH_ROOT}/{quantity}"


def truth_unit(quantity: str) -> str:
    for suffix, unit in _TRUTH_UNITS:
        if quantity.endswith(suffix):
            return unit
    return "1"


class Severity(enum.StrEnum):
    """Text log levels, spelled as Rerun's TextLogLevel."""

    INFO = "INFO"
    WARN = "WARN"
    ERROR = "ERROR"


# --- Sinks ----------------------------------------------------------------------------------
class SinkKind(enum.StrEnum):
    RRD = "rrd"
    SPAWN = "spawn"
    CONNECT = "connect"
    WEB = "web"


DEFAULT_GRPC_PORT = 9876
DEFAULT_WEB_PORT = 9090
VIEWER_BIND_ADDRESS = "127.0.0.1"
"""Where `open_trace(..., web=True)` serves: this machine only (forward the ports to share it)."""


@dataclass(frozen=True)
class TraceSink:
    """Where a trace goes. Several can be combined: `Tracer([TraceSink.rrd(p), TraceSink.spawn()])`.

    On the command line: `TraceSink.parse("rrd:out/trace.rrd")`, "spawn", "connect",
    "connect:rerun+http://host:9876/proxy", "web", "web:9090".
    """

    kind: SinkKind
    path: Path | None = None
    url: str | None = None
    port: int | None = None

    @classmethod
    def rrd(cls, path: str | Path) -> TraceSink:
        """A `.rrd` file (parent folders are created)."""
        return cls(SinkKind.RRD, path=Path(path))

    @classmethod
    def spawn(cls, port: int = DEFAULT_GRPC_PORT) -> TraceSink:
        """Spawn a native viewer listening on `port` (or reuse one already there) and stream to it."""
        return cls(SinkKind.SPAWN, port=port)

    @classmethod
    def connect(cls, url: str = f"rerun+http://127.0.0.1:{DEFAULT_GRPC_PORT}/proxy") -> TraceSink:
        """Stream to a running viewer or `rerun --serve-grpc` (e.g. the compose `viewer` service)."""
        return cls(SinkKind.CONNECT, url=url)

    @classmethod
    def serve_web(cls, port: int = DEFAULT_WEB_PORT, grpc_port: int = DEFAULT_GRPC_PORT) -> TraceSink:
        """Serve the web viewer on http://localhost:`port` (no display needed); the data is kept in
        an in-process gRPC server on `grpc_port` for as long as this process lives."""
        return cls(SinkKind.WEB, port=port, url=f"{grpc_port}")

    @classmethod
    def parse(cls, spec: str) -> TraceSink:
        """'rrd:PATH' | 'spawn[:PORT]' | 'connect[:URL]' | 'web[:PORT[:GRPC_PORT]]'."""
        kind, _, arg = spec.partition(":")
        try:
            sink_kind = SinkKind(kind)
        except ValueError:
            raise unknown_name("trace sink", kind, [k.value for k in SinkKind]) from None
        if sink_kind is SinkKind.RRD:
            if not arg:
                raise ValueError("trace sink 'rrd' needs a path: rrd:out/trace.rrd")
            return cls.rrd(arg)
        if sink_kind is SinkKind.SPAWN:
            return cls.spawn(int(arg)) if arg else cls.spawn()
        if sink_kind is SinkKind.CONNECT:
            return cls.connect(arg) if arg else cls.connect()
        if not arg:
            return cls.serve_web()
        web_port, _, grpc_port = arg.partition(":")
        return cls.serve_web(int(web_port), int(grpc_port)) if grpc_port else cls.serve_web(int(web_port))

    def __str__(self) -> str:
        """The spelling `parse` reads: 'rrd:out/trace.rrd', 'spawn:9876', 'web:9090', 'connect:URL'."""
        if self.kind is SinkKind.RRD:
            return f"rrd:{self.path}"
        if self.kind is SinkKind.CONNECT:
            return f"connect:{self.url}"
        if self.kind is SinkKind.WEB:
            return f"web:{self.port}:{self.url}"
        return f"{self.kind.value}:{self.port}"


LIVE_TRACE_ENV = "HIL_TRACE"
"""Live sinks for every traced run (comma-separated, as `TraceSink.parse` reads them, no rrd):
`hilrig sim` takes them as its default --viewer and pytest scenarios stream to them, beside the
trace.rrd they always write. The compose file sets it to the viewer service's address."""


def parse_live_sink(text: str) -> TraceSink:
    """A live sink (spawn, web or connect); ValueError for a file sink or a bad spelling."""
    try:
        sink = TraceSink.parse(text)
    except (ValueError, RigError) as error:  # an unknown kind, a port that is no number
        raise ValueError(
            f"{text!r}: {error} (spawn[:PORT], web[:PORT[:GRPC_PORT]] or connect[:URL])"
        ) from None
    if sink.kind is SinkKind.RRD:
        raise ValueError(f"{text!r}: the trace file is always written; name a live sink here")
    return sink


def live_sinks_from_environment(environ: Mapping[str, str] = os.environ) -> list[TraceSink]:
    """The live sinks $HIL_TRACE names (none when unset); ValueError naming the variable."""
    sinks = []
    for part in filter(None, (p.strip() for p in environ.get(LIVE_TRACE_ENV, "").split(","))):
        try:
            sinks.append(parse_live_sink(part))
        except ValueError as error:
            raise ValueError(f"${LIVE_TRACE_ENV}: {error}") from None
    return sinks


# --- The tracer -----------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class _CycleRow:
    cycle: int
    time_s: float
    groups: tuple[tuple[Sequence[str], Sequence[Value]], ...]
    """(names, values) pairs: one per PDO, or one per dict given to `log_cycle`."""
    truth: JointState | None  # None: real time without physics


def default_latency(sinks: Sequence[TraceSink]) -> float | None:
    """How old the newest traced cycle may get before a batch goes out: LIVE_LATENCY_S when a
    viewer watches (spawned, connected or served), None (whole batches only) for files alone."""
    return LIVE_LATENCY_S if any(sink.kind is not SinkKind.RRD for sink in sinks) else None


@dataclass(frozen=True, slots=True)
class _HistorySpan:
    """What a Rig recorded between two marks of its History: one batch for the sender."""

    history: History
    start: HistoryMark
    end: HistoryMark


_Part = tuple[Sequence[str], np.ndarray, np.ndarray, np.ndarray]
"""(names, cycles, times, values matrix with one column per name)."""
_RowSet = tuple[np.ndarray, np.ndarray, Sequence[tuple[str, np.ndarray]]]
"""(cycles, times, series): series (path, values) over the same rows."""
_Batch = list[_CycleRow | CycleResult] | _HistorySpan | Callable[[], None]


class Tracer(RigObserver):
    """Logs the rig's cycles, NMT changes, EMCYs and SDO aborts to Rerun.

    sink: one `TraceSink` or several. table: names -> kinds and units (RigTable.load()).
    blueprint: name in `dashboards.BLUEPRINTS` sent with the trace (None: the viewer's own).
    batch_cycles: cycles per batch at most. max_latency_s: also hand a batch over when this much
    wall time passed since the last one (default: LIVE_LATENCY_S with a live sink, never for .rrd
    files alone). background: pivot and send batches in a thread (True) or
    inline on the caller's thread at each batch boundary (False). clock: "simulation" (lockstep:
    `sim_time` timeline) or "wall" (real-time mode: `t` is Unix time, `wall_time` timeline).

    As a `RigObserver` it gets every cycle result (kept as it is until its batch is sent, so a
    traced cycle costs one list append) and event. `log_cycle` takes one cycle's values as
    dicts instead (logs replayed into a trace). The event methods may be called from any
    thread (EMCY and heartbeats arrive in canopen's receive thread). Call `close()` at the end:
    it sends what is pending and flushes the sinks. Usable as a context manager.
    """

    def __init__(
        self,
        sink: TraceSink | Sequence[TraceSink],
        table: RigTable,
        *,
        blueprint: str | None = "overview",
        batch_cycles: int = DEFAULT_BATCH_CYCLES,
        max_latency_s: float | None = None,
        background: bool = True,
        clock: Clock = "simulation",
        recording_name: str | None = None,
        root: str = "",
        share: Tracer | None = None,
    ) -> None:
        import rerun as rr  # slow (about 12 s in the emulated VM): only when tracing

        if batch_cycles < 1:
            raise ValueError(f"batch_cycles: expected >= 1, got {batch_cycles}")
        import pyarrow as pa  # loaded by rerun

        self._rr = rr
        self._pa = pa
        self._scalars = rr.Scalars.descriptor_scalars()
        # The Arrow schema of each group of entities sent together (`_send_group`): the same
        # groups come back every batch (a PDO's fields, the truth).
        self._group_schemas: dict[tuple[str, ...], Any] = {}
        # Their columns: a Scalars field per entity (`_scalars_field`), made when its series is
        # named, ahead of the run, and the two index fields (`_group_schema`).
        self._scalars_fields: dict[str, Any] = {}
        self._index_fields: list[Any] | None = None
        # The static SeriesLines components (`_name_many`), as rerun's own batches convert them.
        self._line_names = rr.SeriesLines.descriptor_names()
        self._line_mode = rr.SeriesLines.descriptor_interpolation_mode()
        self._line_aggregation = rr.SeriesLines.descriptor_aggregation_policy()
        self._step_after = rr.components.InterpolationModeBatch(
            rr.components.InterpolationMode.StepAfter
        ).as_arrow_array()
        self._min_max = rr.components.AggregationPolicyBatch(
            rr.components.AggregationPolicy.MinMax
        ).as_arrow_array()
        self.table = table
        self.sinks: tuple[TraceSink, ...] = (sink,) if isinstance(sink, TraceSink) else tuple(sink)
        if not self.sinks and share is None:
            raise ValueError("Tracer needs at least one sink")
        if root and (not root.startswith("/") or root.endswith("/")):
            raise ValueError(f"root: expected an entity path like /modules/3, got {root!r}")
        self.root = root
        """Prefix of every entity path this tracer writes ("" for one board; a robot's modules
        each have their own, e.g. /modules/3, on one recording)."""
        self.batch_cycles = batch_cycles
        self.max_latency_s = max_latency_s if max_latency_s is not None else default_latency(self.sinks)
        self._next_hand_over = time.monotonic() + (self.max_latency_s or 0.0)
        self.clock: Clock = clock
        self.time_timeline = SIM_TIME_TIMELINE if clock == "simulation" else WALL_TIME_TIMELINE
        self.web_url: str | None = None
        """The page of the served web viewer (with the data's address), when a web sink is used."""
        self._handed_over_cycles = 0  # cycles logged and handed to the sender (cycles_logged)
        self._look_at = 1  # on_cycle looks further once this many cycles are pending
        self._params: JointParams | None = None
        self._paths = {name: root + path for name, path in self._entity_paths(table).items()}
        self._named: set[str] = set()  # entities whose static SeriesLines name was sent
        self._polled: dict[str, int] = {}  # field -> every how many cycles it is read over SDO
        # Entities whose values have names (board.toml enums and bitsets): each change of value
        # also goes in as a TextLog at <entity>/label, so the viewer shows "velocity" beside 1.
        self._value_names: dict[str, ValueEnum | BitSet] = {
            self._paths[name]: values for name, values in table.board.named_values.items()
        }
        self._last_named_value: dict[str, float] = {}
        self._last_held_value: dict[str, float] = {}  # of series sent as their changes
        # Values that hold until changed are drawn as steps, not as slopes between samples: a
        # command or parameter (sent when it changes), a state with named values (control_mode,
        # fault_flags), and a field read over SDO now and then (on_polled adds those); a
        # measured signal stays linear.
        self._held: set[str] = {
            self._paths[entry.name]
            for entry in table.board.entries
            if isinstance(entry, Field) and entry.kind in (Kind.COMMAND, Kind.PARAMETER)
        } | set(self._value_names)
        self._held.add(self.root + truth_path(TRUE_SPRING_STIFFNESS))  # a parameter of the plant
        # PDOs seen on the bus (label -> layout): each gets a frames-per-cycle series, 0 in the
        # cycles it did not come (a TPDO due every 10th SYNC, one that went missing).
        self._framed: dict[str, PdoLayout] = {}
        self._pending: list[_CycleRow | CycleResult] = []
        # Following a Rig's History (on_history): a cycle costs a count; a batch is the span
        # between two marks, taken from the history's own per-PDO rows as columns.
        self._history: History | None = None
        self._history_mark: HistoryMark | None = None
        self._history_cycles = 0
        self._name_ahead = False  # name the history's series on the sender before its first batch
        self._lock = threading.Lock()  # guards the swap of _pending, and _params (event threads)
        self._closed = False
        self._error: BaseException | None = None

        self._owns_recording = share is None
        self._live_urls: list[str] = []  # the gRPC addresses of the live sinks (send_blueprint)
        if share is not None:  # another tracer's recording and sinks (a robot's module)
            self.recording = share.recording
            self.sinks = share.sinks
            self._live_urls = share._live_urls
        else:
            self.recording = rr.RecordingStream(APPLICATION_ID, recording_id=recording_name)
            self._attach_sinks()
        if blueprint is not None:
            self.send_blueprint(load_blueprint(blueprint))

        self._queue: queue.SimpleQueue[_Batch | None] | None = None
        self._worker: threading.Thread | None = None
        if background:
            self._queue = queue.SimpleQueue()
            self._worker = threading.Thread(target=self._work, name="hilrig-trace", daemon=True)
            self._worker.start()

    @classmethod
    def for_scenario(cls, out_dir: str | Path, table: RigTable, **kwargs: Any) -> Tracer:
        """A tracer writing `<out_dir>/trace.rrd`, beside the scenario's bus.log."""
        return cls(
            TraceSink.rrd(Path(out_dir) / "trace.rrd"), table, recording_name=Path(out_dir).name, **kwargs
        )

    # --- Sinks ------------------------------------------------------------------------------
    def _attach_sinks(self) -> None:
        rr = self._rr
        native: list[Any] = []
        for sink in self.sinks:
            if sink.kind is SinkKind.RRD:
                assert sink.path is not None
                sink.path.parent.mkdir(parents=True, exist_ok=True)
                native.append(rr.FileSink(str(sink.path)))
            elif sink.kind is SinkKind.SPAWN:
                port = sink.port or DEFAULT_GRPC_PORT
                rr.spawn(port=port, connect=False)
                url = f"rerun+http://127.0.0.1:{port}/proxy"
                native.append(rr.GrpcSink(url))
                self._live_urls.append(url)
            elif sink.kind is SinkKind.CONNECT:
                native.append(rr.GrpcSink(sink.url))
                self._live_urls.append(sink.url)
            else:
                server = rr.GrpcServerSink(port=int(sink.url or DEFAULT_GRPC_PORT))
                native.append(server)
                self._live_urls.append(server.uri)
                port = sink.port or DEFAULT_WEB_PORT
                rr.serve_web_viewer(web_port=port, open_browser=False, connect_to=server.uri)
                self.web_url = web_viewer_url(port, int(sink.url or DEFAULT_GRPC_PORT))
        self.recording.set_sinks(*native)

    # --- What the Rig calls -----------------------------------------------------------------
    def log_plant_params(self, params: JointParams) -> None:
        """The plant's parameters: the true spring constant is logged every cycle from now on."""
        with self._lock:
            self._params = params

    def log_cycle(
        self,
        cycle: int,
        t: float,
        received: Mapping[str, Value],
        sent: Mapping[str, Value],
        truth: JointState | None,
    ) -> None:
        """One completed lockstep cycle: TPDO values, RPDO values, the plant state at its start
        (real time: the tick's values and the plant at the tick; None without physics).

        Cheap: one append; every `batch_cycles` cycles the batch goes to the sender.
        """
        row = _CycleRow(
            cycle,
            t,
            ((tuple(received), tuple(received.values())), (tuple(sent), tuple(sent.values()))),
            truth,
        )
        self._append(row)

    def _append(self, row: _CycleRow | CycleResult) -> None:
        # The rig's thread alone appends and hands over (no lock on this path: it runs every cycle).
        self._check_open()
        self._pending.append(row)
        if self._batch_due(len(self._pending)):
            self._hand_over()

    def _batch_due(self, pending: int) -> bool:
        """A whole batch is pending, or a live viewer has waited `max_latency_s` for one."""
        return pending >= self.batch_cycles or (
            self.max_latency_s is not None and time.monotonic() >= self._next_hand_over
        )

    @property
    def cycles_logged(self) -> int:
        """Cycles logged so far (by `log_cycle`, or as an observer of a rig)."""
        return self._handed_over_cycles + self.pending_cycles

    @property
    def pending_cycles(self) -> int:
        """Cycles logged but not handed to the sender yet (close() sends them)."""
        return len(self._pending) + self._history_cycles

    # --- As an observer of a Rig --------------------------------------------------------
    def on_params(self, params: JointParams) -> None:
        self.log_plant_params(params)

    def on_history(self, history: History) -> None:
        if self.cycles_logged == 0 and self._history is None:
            self._history = history
            self._history_mark = history.mark()
            self._name_ahead = True

    def on_configured(self, *, truth: bool) -> None:
        # The node's PDOs are known: name their series now, before the first cycle, and let
        # Rerun write them (and the start's events) before it too. Each of those ~60 one-row
        # chunks costs Rerun's encoder about as much as a 2000-row one; left to run beside the
        # first cycles, that work took the emulated VM's other CPU from the firmware.
        if self._name_ahead and not self._closed:
            self._name_ahead = False
            self.submit(functools.partial(self._name_history_series, truth=truth))
            self.settle()

    def on_polled(self, names: tuple[str, ...], every_cycles: int) -> None:
        with self._lock:
            self._polled.update(dict.fromkeys(names, every_cycles))
            self._held |= {self._paths[name] for name in names}

    def on_cycle(self, result: CycleResult) -> None:
        if self._history is None:
            self._append(result)
            return
        # The rig recorded this cycle in its History already: only count it. This runs every
        # cycle on the rig's thread, so the rest waits for a cycle that may need it (`_look_at`).
        pending = self._history_cycles = self._history_cycles + 1
        if pending >= self._look_at:
            self._counted(pending)

    def _counted(self, pending: int) -> None:
        """A followed History's cycle where something may be due: the first (name the series if
        no `on_configured` did), a whole batch, a live sink's latency, or a closed tracer."""
        self._check_open()
        if self._name_ahead:  # attached after the rig started: the node's PDOs are known now
            self._name_ahead = False
            assert self._history is not None
            truth = self._history.cycles > 0  # the truth is in when the rig has a plant
            self.submit(functools.partial(self._name_history_series, truth=truth))
        # From here on, look every cycle only when a live sink's latency may make one due.
        self._look_at = self.batch_cycles if self.max_latency_s is None else 1
        if self._batch_due(pending):
            self._hand_over()

    def on_nmt(self, state: NmtState, t: float, *, cycle: int | None, source: str) -> None:
        self.log_nmt(state, t, cycle=cycle, source=source)

    def on_emcy(self, record: EmcyRecord) -> None:
        self.log_emcy(record)

    def on_sdo_write(self, name: str, value: float, *, cycle: int, t: float) -> None:
        self.log_sdo_write(name, value, cycle=cycle, t=t)

    def on_sdo_abort(self, what: str, code: int, *, cycle: int, t: float) -> None:
        self.log_sdo_abort(what, code, cycle=cycle, t=t)

    def on_event(self, path: str, text: str, *, warning: bool, cycle: int, t: float) -> None:
        self.log_text(self.root + path, text, Severity.WARN if warning else Severity.INFO, t=t, cycle=cycle)

    def log_sdo_write(self, name: str, value: Value, *, cycle: int, t: float) -> None:
        """A value the rig wrote by SDO (a parameter, or a command no RPDO carries)."""
        self._check_open()
        path = self._paths[name]
        self._send_group([cycle], [t], [(path, np.array([float(value)]))])

    def log_nmt(
        self, state: NmtState, t: float, *, cycle: int | None = None, source: str = "command"
    ) -> None:
        """An NMT state change (by a command the rig sent, or seen in a heartbeat/boot-up)."""
        level = Severity.WARN if state in (NmtState.STOPPED, NmtState.INITIALISING) else Severity.INFO
        where = "boot-up" if state is NmtState.INITIALISING else state.name
        text = f"NMT {where} ({source}) at t = {t:.6g} s"
        self.log_text(self.root + NMT_PATH, text, level, t=t, cycle=cycle)

    def log_emcy(self, record: EmcyRecord) -> None:
        """An EMCY; code 0x0000 (error reset) is INFO, anything else ERROR."""
        level = Severity.INFO if record.code == 0 else Severity.ERROR
        self.log_text(self.root + EMCY_PATH, str(record), level, t=record.time_s, cycle=record.cycle)

    def log_sdo_abort(self, what: str, code: int, *, cycle: int, t: float) -> None:
        """An SDO transfer the node refused (`what` is the rig's message, with the code in words)."""
        self.log_text(
            self.root + SDO_PATH,
            f"SDO abort 0x{code:08X}: {what} at t = {t:.6g} s (cycle {cycle})",
            Severity.WARN,
            t=t,
            cycle=cycle,
        )

    def log_text(self, path: str, text: str, level: Severity, *, t: float, cycle: int | None) -> None:
        """A text log entry at `path` (rare events: sent at once, not batched)."""
        self._check_open()
        rr = self._rr
        indexes = [self._time_column([t])]
        if cycle is not None:
            indexes.insert(0, rr.TimeColumn(CYCLE_TIMELINE, sequence=[cycle]))
        self.recording.send_columns(
            path, indexes=indexes, columns=rr.TextLog.columns(text=[text], level=[level.value])
        )

    def close(self) -> None:
        """Send what is pending, stop the sender thread and flush every sink. Idempotent.

        A served web viewer keeps serving the data until this process exits.
        """
        if self._closed:
            return
        self._hand_over()
        self._closed = True
        self._look_at = 0  # a cycle after this is an error (`_counted`)
        if self._worker is not None and self._queue is not None:
            self._queue.put(None)
            self._worker.join()
        self.recording.flush()
        if self._owns_recording and not any(s.kind is SinkKind.WEB for s in self.sinks):
            self.recording.disconnect()
        if self._error is not None:
            raise RuntimeError(f"tracing failed in the sender thread: {self._error}") from self._error

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # --- Batching ---------------------------------------------------------------------------
    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("Tracer is closed")

    def _hand_over(self) -> None:
        if self.max_latency_s is not None:
            self._next_hand_over = time.monotonic() + self.max_latency_s
        with self._lock:
            rows, self._pending = self._pending, []
        self._handed_over_cycles += len(rows) + self._history_cycles
        batch: list[_Batch] = [rows] if rows else []
        if self._history is not None and self._history_cycles:
            assert self._history_mark is not None
            end = self._history.mark()
            batch.append(_HistorySpan(self._history, self._history_mark, end))
            self._history_mark, self._history_cycles = end, 0
        for part in batch:
            if self._queue is not None:
                self._queue.put(part)
            else:
                self._send(part)

    def _work(self) -> None:
        assert self._queue is not None
        while (batch := self._queue.get()) is not None:
            if self._error is not None:
                continue
            try:
                self._send(batch)
            except BaseException as error:  # reported by close(); the lockstep loop never waits
                self._error = error

    def send_blueprint(self, blueprint: rrb.Blueprint) -> None:
        """The layout a viewer opens this recording with (a dashboard's).

        In the recording, and so in its .rrd, only as the default: a blueprint that is also the
        active one in the file wins over the dashboard `hilrig view --dashboard` loads beside it
        (measured: the viewer showed the file's). A live viewer is told to show it at once, over
        a stream of its own to the live sinks alone."""
        self.recording.send_blueprint(blueprint, make_active=False, make_default=True)
        rr = self._rr
        for url in self._live_urls:
            stream = rr.RecordingStream(
                APPLICATION_ID, recording_id=self.recording.get_recording_id(), send_properties=False
            )
            stream.connect_grpc(url)
            try:
                stream.send_blueprint(blueprint, make_active=True, make_default=True)
                stream.flush()
            finally:
                stream.disconnect()

    def settle(self, timeout_s: float = SETTLE_TIMEOUT_S) -> bool:
        """Wait until what was logged and submitted so far is in Rerun's hands and written to
        the sinks (a file's bytes on disk, a live viewer's sent). False when that took longer
        than `timeout_s` (a live viewer not reachable yet): nothing is lost, the rest is written
        while the caller goes on. A closed tracer raises (`submit`)."""
        settled = threading.Event()

        def flush() -> None:
            try:
                self.recording.flush(timeout_sec=timeout_s)
                settled.set()
            except RuntimeError:  # Rerun's "flush timed out": still queued, not an error
                pass

        self.submit(flush)
        return settled.wait(timeout_s)

    def submit(self, work: Callable[[], None]) -> None:
        """Run `work` (sending something to the recording) on the sender thread, in order with
        the batches (inline without one)."""
        self._check_open()
        if self._queue is not None:
            self._queue.put(work)
        else:
            work()

    def module_tracer(self, node_id: int) -> Tracer:
        """A tracer for module `node_id` of a robot: its paths under /modules/<id>, on this
        tracer's recording and sinks (close it before this one)."""
        return Tracer(
            (),
            self.table,
            blueprint=None,
            batch_cycles=self.batch_cycles,
            max_latency_s=self.max_latency_s,
            background=self._worker is not None,
            clock=self.clock,
            root=module_root(node_id),
            share=self,
        )

    def robot_observer(self, chain: ChainModel) -> ChainTrace:
        """The robot's own trace on this recording: its 3D view and its events."""
        return ChainTrace(self, chain)

    def _send(self, batch: _Batch) -> None:
        if callable(batch):
            batch()
            return
        if isinstance(batch, _HistorySpan):
            self._send_span(batch)
        else:
            self._send_batch(batch)

    def _name_history_series(self, *, truth: bool) -> None:
        """Name the series a Rig's history fills (each PDO's fields and frame count, the truth)
        on the sender, ahead of the first batch: naming 45 series is a third of what a first
        batch costs, and the sender does it while the rig runs, not when the run ends (close()).
        Only series the history has a PDO for: a name alone is no data (`trace_gaps` still
        reports a series without rows)."""
        assert self._history is not None
        series: list[tuple[str, str | None, bool]] = []
        framed = False
        for layout in self._history.layouts():
            series += [(self._paths[name], None, False) for name in layout.names]
            if layout.enabled and layout.cob_id:
                series.append((self.root + frames_path(layout), _frames_series_name(layout), True))
                framed = True
        if framed:  # the frames of each direction per cycle (`_send_frames`)
            series += self._bus_totals_series()
        if truth:  # the truth too, when the rig has a plant, and its spring constant
            series += [(self.root + truth_path(quantity), None, False) for quantity in TRUTH_QUANTITIES]
        self._name_many(series)
        for path, _, _ in series:  # the columns of the batches to come, made while nothing runs
            self._scalars_field(path)

    def _send_span(self, span: _HistorySpan) -> None:
        """A span of a Rig's History: its per-PDO rows come as columns (the payloads as the bus
        carried them, read by numpy: no per-cycle work here)."""
        history = span.history
        parts: list[_Part] = []
        frames: list[tuple[PdoLayout, np.ndarray]] = []
        for layout, cycle_column, matrix in history.blocks_between(span.start, span.end):
            parts.append((layout.names, cycle_column, history.times_of(cycle_column), matrix))
            frames.append((layout, cycle_column))
        cycles, states = history.truth_between(span.start, span.end)
        every_cycle = np.asarray(cycles, dtype=np.int64)
        times = history.times_of(cycles)
        self._send_parts(parts, also=self._truth_row_sets(every_cycle, times, states))
        if states:  # the spring constant's changes go with the frame counts' (mostly the same rows)
            stiffness = self._spring_stiffness_series(len(every_cycle))
            self._send_frames(frames, every_cycle, times, also=stiffness)

    def _send_batch(self, batch: list[_CycleRow | CycleResult]) -> None:
        """Rows (log_cycle, or cycles of a Rig not followed through its History): pivoted into
        one column per entity and sent with `send_columns`.

        Values are grouped by the PDO (or dict) that carried them, so a group of N cycles becomes
        one N x k array in one numpy call, and each of its k columns one entity's column."""
        # Keyed by the identity of the names tuple (every PDO layout holds one, shared by all its
        # rows; a `log_cycle` row has its own): per row and group the index and values are appended.
        groups: dict[int, tuple[Sequence[str], list[int], list[Sequence[Value]]]] = {}
        for index, row in enumerate(batch):
            if isinstance(row, _CycleRow):
                pairs: Iterable[tuple[Sequence[str], Sequence[Value]]] = row.groups
            else:
                pairs = [(pdo.names, values) for pdo, values in (*row.received_rows, *row.sent_rows)]
            for names, values in pairs:
                entry = groups.get(id(names))
                if entry is None:
                    entry = groups[id(names)] = (names, [], [])
                entry[1].append(index)
                entry[2].append(values)
        all_cycles = np.asarray([row.cycle for row in batch], dtype=np.int64)
        all_times = np.asarray([row.time_s for row in batch], dtype=np.float64)
        parts: list[_Part] = []
        for names, indexes, rows in groups.values():
            if not names:
                continue
            matrix = _matrix(rows, len(names))
            parts.append((names, all_cycles[indexes], all_times[indexes], matrix))
        with_truth = [i for i, row in enumerate(batch) if row.truth is not None]
        truth_cycles, truth_times = all_cycles[with_truth], all_times[with_truth]
        states: list[JointState] = [batch[i].truth for i in with_truth]  # type: ignore[misc]
        self._send_parts(parts, also=self._truth_row_sets(truth_cycles, truth_times, states))
        self._send_spring_stiffness(truth_cycles, truth_times)

        results = [row for row in batch if isinstance(row, CycleResult)]
        if results:
            cycles_of: dict[PdoLayout, list[int]] = {}
            for result in results:
                for pdo, _ in (*result.received_rows, *result.sent_rows):
                    cycles_of.setdefault(pdo, []).append(result.cycle)
            frames = [(pdo, np.asarray(c, dtype=np.int64)) for pdo, c in cycles_of.items()]
            every_cycle = np.asarray([r.cycle for r in results], dtype=np.int64)
            self._send_frames(frames, every_cycle, np.asarray([r.time_s for r in results]))

    def _send_parts(self, parts: Sequence[_Part], also: Sequence[_RowSet] = ()) -> None:
        """Each part's fields, and the series of `also`, sent by `_send_row_sets` (series over the
        same cycles as one group); a field that came in several parts (several PDOs, or sent and
        received) merged in cycle order first."""
        paths = self._paths
        parts_of: dict[str, int] = {}
        for names, *_ in parts:
            for name in names:
                parts_of[paths[name]] = parts_of.get(paths[name], 0) + 1
        row_sets: list[_RowSet] = []
        merged: dict[str, list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = {}
        for names, cycle_column, time_column, matrix in parts:
            group: list[tuple[str, np.ndarray]] = []
            for i, name in enumerate(names):
                path = paths[name]
                if parts_of[path] == 1:
                    group.append((path, matrix[:, i]))
                else:
                    merged.setdefault(path, []).append((cycle_column, time_column, matrix[:, i]))
            if group:
                row_sets.append((cycle_column, time_column, group))
        for path, columns in merged.items():  # one timeline per entity
            cycle_column = np.concatenate([c[0] for c in columns])
            order = np.argsort(cycle_column, kind="stable")
            time_column = np.concatenate([c[1] for c in columns])[order]
            values = np.concatenate([c[2] for c in columns])[order]
            row_sets.append((cycle_column[order], time_column, [(path, values)]))
        self._send_row_sets([*row_sets, *also])

    def _send_row_sets(self, row_sets: Iterable[_RowSet]) -> None:
        """Series over the same cycles go as one group (`_send_group`): the PDOs due every cycle
        and the truth are one record batch, one call into Rerun, not one per PDO. Each call has
        a fixed cost (the batch's schema read, its chunks handed to Rerun's batcher: natively
        about 0.3 ms, twenty times that in the emulated VM), which was most of what a batch of
        a 2000-cycle run cost."""
        groups: dict[bytes, _RowSet] = {}
        for cycles, times, series in row_sets:
            key = np.asarray(cycles, dtype=np.int64).tobytes()
            known = groups.get(key)
            if known is None:
                groups[key] = (cycles, times, list(series))
            else:
                known[2].extend(series)  # type: ignore[attr-defined]
        for cycles, times, series in groups.values():
            self._send_group(cycles, times, series)

    def _send_frames(
        self,
        frames: Sequence[tuple[PdoLayout, np.ndarray]],
        every_cycle: np.ndarray,
        times: np.ndarray,
        also: Sequence[tuple[str, np.ndarray]] = (),
    ) -> None:
        """Frames per cycle of every PDO seen so far (a row of a PDO is one frame on the bus),
        and their sums per direction, over `every_cycle` (consecutive cycles), as their changes;
        with them the step series of `also` (over the same cycles)."""
        if not len(every_cycle):
            return
        first, count = int(every_cycle[0]), len(every_cycle)
        for pdo, _ in frames:
            if pdo.enabled and pdo.cob_id:  # not the rows of fields read over SDO
                self._framed.setdefault(pdo.label, pdo)
        series = list(also)
        if self._framed:
            # Every PDO's count per cycle in one bincount: row k of the matrix is PDO k's.
            row_of = {label: k for k, label in enumerate(self._framed)}
            seen = [(row_of[pdo.label], cycles) for pdo, cycles in frames if pdo.label in row_of]
            counts = np.zeros((len(row_of), count))
            if seen:
                offsets = np.concatenate([cycles for _, cycles in seen]).astype(np.int64) - first
                lengths = [len(cycles) for _, cycles in seen]
                rows = np.repeat(np.array([k for k, _ in seen], np.int64), lengths)
                inside = (offsets >= 0) & (offsets < count)
                flat = rows[inside] * count + offsets[inside]
                counts += np.bincount(flat, minlength=counts.size).reshape(counts.shape)
            pdos = list(self._framed.values())
            series += [(self.root + frames_path(pdo), counts[k]) for k, pdo in enumerate(pdos)]
            for path, direction in _BUS_TOTALS:
                series.append(
                    (self.root + path, counts[[pdo.direction is direction for pdo in pdos]].sum(axis=0))
                )
            named = [(self.root + frames_path(pdo), _frames_series_name(pdo), True) for pdo in pdos]
            self._name_many([*named, *self._bus_totals_series()])  # named ahead, for a Rig's History
        self._send_changes(every_cycle, times, series)

    def _bus_totals_series(self) -> list[tuple[str, str, bool]]:
        """(path, series name, counts) of the frames per cycle of each direction (`_name_many`)."""
        return [
            (self.root + path, f"{direction.value}s per cycle [frames]", True)
            for path, direction in _BUS_TOTALS
        ]

    def _truth_row_sets(
        self, cycles: np.ndarray, times: np.ndarray, states: Sequence[JointState]
    ) -> list[_RowSet]:
        """The truth's series over these plant states, as the row set `_send_parts` sends with
        the PDOs' (none without states)."""
        if not states:
            return []
        matrix = state_matrix(states)
        series = [
            (self.root + truth_path(quantity), matrix[:, STATE_FIELDS.index(quantity)])
            for quantity in TRUTH_QUANTITIES[:-1]
        ]
        return [(cycles, times, series)]

    def _send_spring_stiffness(self, cycles: np.ndarray, times: np.ndarray) -> None:
        """The plant's spring constant over these cycles (a parameter: as its changes)."""
        if len(cycles):
            self._send_changes(cycles, times, self._spring_stiffness_series(len(cycles)))

    def _spring_stiffness_series(self, count: int) -> list[tuple[str, np.ndarray]]:
        """The plant's spring constant over `count` cycles, as (path, values) (none before the
        rig gave its parameters)."""
        with self._lock:
            params = self._params
        if params is None:
            return []
        stiffness = np.full(count, params.spring_stiffness_nm_per_rad)
        return [(self.root + truth_path(TRUE_SPRING_STIFFNESS), stiffness)]

    def _send_group(
        self, cycles: Sequence[int], times: Sequence[float], series: Sequence[tuple[str, np.ndarray]]
    ) -> None:
        """Entities over the same rows (`_send_row_sets`): one Arrow record batch, which Rerun
        splits into one chunk per entity, each as `send_columns` would make it. One call for the
        group instead of one per entity: in the emulated VM the Python of each call cost about
        2 ms. An entity not named yet gets its default name first."""
        pa = self._pa
        unnamed = [(path, None, False) for path, _ in series if path not in self._named]
        if unnamed:
            self._name_many(unnamed)
        key = tuple(path for path, _ in series)
        schema = self._group_schemas.get(key)
        if schema is None:
            schema = self._group_schemas[key] = self._group_schema(key)
        cycle_column = np.asarray(cycles, dtype=np.int64)
        time_column = np.asarray(times, dtype=np.float64)
        arrays = [pa.array(cycle_column), self._time_array(time_column)]
        arrays += [pa.array(np.ascontiguousarray(values, dtype=np.float64)) for _, values in series]
        self.recording.send_record_batch(pa.RecordBatch.from_arrays(arrays, schema=schema))
        for path, values in series:
            named = self._value_names.get(path)
            if named is not None:
                self._send_value_names(path, named, cycle_column, time_column, values)

    def _group_schema(self, paths: tuple[str, ...]) -> Any:
        """The record batch of `_send_group`: the cycle and time indexes, a Scalars column per path."""
        pa = self._pa
        if self._index_fields is None:
            self._index_fields = [
                _index_field(pa, CYCLE_TIMELINE, pa.int64()),
                _index_field(pa, *self._time_index()),
            ]
        return pa.schema([*self._index_fields, *(self._scalars_field(path) for path in paths)])

    def _scalars_field(self, path: str) -> Any:
        """The Scalars column of entity `path` in `_send_group`'s batches (made once)."""
        field = self._scalars_fields.get(path)
        if field is None:
            field = _component_field(self._pa, path, self._scalars, self._pa.float64())
            self._scalars_fields[path] = field
        return field

    def _time_index(self) -> tuple[str, Any]:
        """The time timeline of this clock and its Arrow type: sim_time (a duration) in
        lockstep, wall_time (a timestamp) in real time."""
        pa = self._pa
        if self.clock == "simulation":
            return SIM_TIME_TIMELINE, pa.duration("ns")
        return WALL_TIME_TIMELINE, pa.timestamp("ns")

    def _time_array(self, times: np.ndarray) -> Any:
        """Seconds as the time index's Arrow array, converted as `rr.TimeColumn` converts them."""
        arrow_type = self._time_index()[1]
        numpy_type = "timedelta64[ns]" if self.clock == "simulation" else "datetime64[ns]"
        return self._pa.array((times * 1e9).astype(numpy_type), arrow_type)

    def _send_changes(
        self, cycles: np.ndarray, times: np.ndarray, series: Sequence[tuple[str, np.ndarray]]
    ) -> None:
        """Step series over consecutive `cycles`: of each, only the rows where the value differs
        from the one before (across batches) and the last row of the batch, which carries the
        line to the batch's end. Read back, the latest row at or before a cycle is its value.
        Series with the same rows (counts that never change) go as one group."""
        if not len(cycles):
            return
        groups: dict[bytes, tuple[np.ndarray, list[tuple[str, np.ndarray]]]] = {}
        for path, values in series:
            keep = _changed(self._last_held_value, path, values)
            keep[-1] = True
            rows = np.flatnonzero(keep)
            groups.setdefault(rows.tobytes(), (rows, []))[1].append((path, values[rows]))
        for rows, group in groups.values():
            self._send_group(cycles[rows], times[rows], group)

    def _name_many(self, series: Sequence[tuple[str, str | None, bool]]) -> None:
        """The static SeriesLines of each (path, name, counts) not named yet, in one static record
        batch: its series name (default: from the field or truth), drawn as steps if it holds its
        value; `counts` (frames per cycle): as steps and, zoomed out, as the band between the
        fewest and the most (the viewer's average would hide one missing frame among a thousand)."""
        pa = self._pa
        fields: list[Any] = []
        arrays: list[Any] = []
        for path, name, counts in series:
            if path in self._named:
                continue
            self._named.add(path)
            series_name = name if name is not None else self._series_name(path)
            fields.append(_component_field(pa, path, self._line_names, pa.string()))
            arrays.append(pa.array([series_name], pa.string()))
            if counts or path in self._held:
                fields.append(_component_field(pa, path, self._line_mode, self._step_after.type))
                arrays.append(self._step_after)
            if counts:
                fields.append(_component_field(pa, path, self._line_aggregation, self._min_max.type))
                arrays.append(self._min_max)
        if fields:
            batch = pa.RecordBatch.from_arrays(arrays, schema=pa.schema(fields))
            self.recording.send_record_batch(batch, index=None)

    def _send_value_names(
        self, path: str, named: ValueEnum | BitSet, cycles: np.ndarray, times: np.ndarray, values: np.ndarray
    ) -> None:
        """The name of each new value (where it differs from the one before), as a TextLog at
        `<path>/label` (a child entity: the number's own entity keeps one component per row)."""
        changed = np.flatnonzero(_changed(self._last_named_value, path, values))
        if not len(changed):
            return
        rr = self._rr
        texts = [f"{path.rsplit('/', 1)[-1]} = {value_name(named, float(values[i]))}" for i in changed]
        self.recording.send_columns(
            label_path(path),
            indexes=[
                rr.TimeColumn(CYCLE_TIMELINE, sequence=cycles[changed].astype(np.int64)),
                self._time_column(times[changed]),
            ],
            columns=rr.TextLog.columns(text=texts, level=[Severity.INFO.value] * len(texts)),
        )

    def _time_column(self, times: Sequence[float]) -> rr.TimeColumn:
        if self.clock == "simulation":
            return self._rr.TimeColumn(SIM_TIME_TIMELINE, duration=np.asarray(times, dtype=np.float64))
        return self._rr.TimeColumn(WALL_TIME_TIMELINE, timestamp=np.asarray(times, dtype=np.float64))

    # --- Names ------------------------------------------------------------------------------
    @staticmethod
    def _entity_paths(table: RigTable) -> dict[str, str]:
        paths: dict[str, str] = {}
        for entry in table.board.entries:
            if isinstance(entry, Field):
                paths[entry.name] = field_path(entry)
            elif entry.direction is IoDirection.INPUT:
                paths[entry.name] = f"{HIL_INPUTS_ROOT}/{entry.name}"
            else:
                paths[entry.name] = f"{HIL_OUTPUTS_ROOT}/{entry.name}"
        return paths

    def path_of(self, name: str) -> str:
        """Entity path of a board field or HIL I/O object (FieldNameError with close matches)."""
        self.table.entry(name)
        return self._paths[name]

    def _series_name(self, path: str) -> str:
        name = path.rsplit("/", 1)[-1]
        if path.removeprefix(self.root).startswith(TRUTH_ROOT):
            return f"true {name} [{truth_unit(name)}]"
        every = self._polled.get(name)
        polled = f" (SDO, every {every} cycles)" if every is not None else ""
        return f"{name} [{self.table.entry(name).unit}]{polled}"


class ChainTrace(RobotObserver):
    """A robot's 3D view and events on its tracer's recording: each link a capsule at
    /robot/links/<k>, moved by the chain's pose every cycle (batched like the fields: one
    `send_columns` per link and batch, on the tracer's sender thread)."""

    def __init__(self, tracer: Tracer, chain: ChainModel) -> None:
        self._tracer = tracer
        self._chain = chain
        self._cycles: list[int] = []
        self._times: list[float] = []
        self._positions: list[np.ndarray] = []
        self._quaternions: list[np.ndarray] = []
        self._next_hand_over = time.monotonic() + (tracer.max_latency_s or 0.0)
        self._log_geometry()

    def _log_geometry(self) -> None:
        rr = self._tracer._rr
        recording = self._tracer.recording
        geometry = self._chain.geometry
        length, radius = geometry.link_length_m, geometry.link_radius_m
        # A capsule lies along +z from its origin; each link runs back along its frame's -x.
        along_minus_x = rr.RotationAxisAngle(axis=[0.0, 1.0, 0.0], degrees=-90.0)
        for k in range(self._chain.link_count):
            recording.log(
                link_path(k),
                rr.Capsules3D(
                    lengths=[length],
                    radii=[radius],
                    rotation_axis_angles=[along_minus_x],
                    colors=[(70, 130, 180) if k else (220, 120, 40)],  # the head stands out
                    labels=["head" if k == 0 else f"link {k}"],
                ),
                static=True,
            )
        # A patch of ground about the chain's length across, under the chain as it starts (from
        # the head at the origin back along -x): the 3D view frames it and the chain.
        chain_length = length * self._chain.link_count
        extent = 0.6 * chain_length
        recording.log(
            f"{ROBOT_ROOT}/ground",
            rr.Boxes3D(
                half_sizes=[[extent, extent, 0.001]],
                centers=[[-0.5 * chain_length, 0.0, -0.001]],
                colors=[(200, 200, 190)],
            ),
            static=True,
        )

    def on_robot_cycle(self, robot: Robot, cycle: int, t: float) -> None:
        positions, quaternions = self._chain.poses()
        self._cycles.append(cycle)
        self._times.append(t)
        self._positions.append(positions)
        self._quaternions.append(quaternions)
        tracer = self._tracer
        if len(self._cycles) >= tracer.batch_cycles or (
            tracer.max_latency_s is not None and time.monotonic() >= self._next_hand_over
        ):
            self.flush()

    def on_robot_event(self, text: str, *, warning: bool, cycle: int, t: float) -> None:
        level = Severity.WARN if warning else Severity.INFO
        self._tracer.log_text(ROBOT_EVENTS_PATH, text, level, t=t, cycle=cycle)

    def flush(self) -> None:
        """Hand the poses collected so far to the sender (close() of the robot's session)."""
        if self._tracer.max_latency_s is not None:
            self._next_hand_over = time.monotonic() + self._tracer.max_latency_s
        if not self._cycles:
            return
        cycles = np.asarray(self._cycles, dtype=np.int64)
        times = np.asarray(self._times, dtype=np.float64)
        positions = np.stack(self._positions)  # cycles x links x 3
        quaternions = np.stack(self._quaternions)[:, :, [1, 2, 3, 0]]  # MuJoCo wxyz -> Rerun xyzw
        self._cycles, self._times, self._positions, self._quaternions = [], [], [], []
        tracer = self._tracer

        def send() -> None:
            rr = tracer._rr
            indexes = [rr.TimeColumn(CYCLE_TIMELINE, sequence=cycles), tracer._time_column(times)]
            for k in range(positions.shape[1]):
                tracer.recording.send_columns(
                    link_path(k),
                    indexes=indexes,
                    columns=rr.Transform3D.columns(translation=positions[:, k], quaternion=quaternions[:, k]),
                )

        tracer.submit(send)


def _changed(last: dict[str, float], path: str, values: np.ndarray) -> np.ndarray:
    """Where each of `values` differs from the one before it, the first from the last value of
    `path` in `last` (none yet: NaN, which differs from anything); `last` then holds this last."""
    before = last.get(path, np.nan)
    changed = values != np.concatenate(([before], values[:-1]))
    if len(values):
        last[path] = float(values[-1])
    return changed


_RERUN_KIND = b"rerun:kind"
"""Rerun's Arrow field metadata (its `re_sorbet` keys, as `Chunk.to_record_batch` writes them):
what a column of a record batch is, on which entity, and which component of which archetype."""
_RERUN_INDEX_NAME = b"rerun:index_name"
_RERUN_ENTITY_PATH = b"rerun:entity_path"
_RERUN_ARCHETYPE = b"rerun:archetype"
_RERUN_COMPONENT = b"rerun:component"
_RERUN_COMPONENT_TYPE = b"rerun:component_type"


def _index_field(pa: Any, timeline: str, arrow_type: Any) -> Any:
    """A timeline column of a record batch for `send_record_batch`."""
    metadata = {_RERUN_KIND: b"index", _RERUN_INDEX_NAME: timeline.encode()}
    return pa.field(timeline, arrow_type, metadata=metadata)


def _component_field(pa: Any, path: str, descriptor: Any, arrow_type: Any) -> Any:
    """A component column (one value per row) of entity `path` in a record batch: `descriptor`
    (an archetype's `descriptor_*()`) says which component it is."""
    metadata = {
        _RERUN_KIND: b"data",
        _RERUN_ENTITY_PATH: path.encode(),
        _RERUN_ARCHETYPE: descriptor.archetype.encode(),
        _RERUN_COMPONENT: descriptor.component.encode(),
        _RERUN_COMPONENT_TYPE: descriptor.component_type.encode(),
    }
    return pa.field(f"{path}:{descriptor.component}", arrow_type, metadata=metadata)


def _matrix(rows: Iterable[Sequence[Value]], width: int, count: int | None = None) -> np.ndarray:
    """Rows of numbers as a float64 (rows x width) array. Through one flat iterator: about twice
    as fast as np.asarray on a list of tuples, which inspects every tuple (measured natively,
    2300 rows: 190 us against 370 us), and this is most of what a batch costs on our side."""
    if count is None:
        count = len(rows)  # type: ignore[arg-type]
    flat = np.fromiter(itertools.chain.from_iterable(rows), dtype=np.float64, count=count * width)
    return flat.reshape(count, width)


def _frames_series_name(pdo: PdoLayout) -> str:
    """'TPDO3 (0x390) [frames]': the series of a PDO's frames per cycle."""
    return f"{pdo.label} [frames]"


def label_path(path: str) -> str:
    """Where the names of an enum or bitset entity's values go ("velocity" for control_mode 1)."""
    return f"{path}/{LABEL_CHILD}"


def value_name(named: ValueEnum | BitSet, value: float) -> str:
    """'velocity' for control_mode 1, 'motor_encoder_stale|output_encoder_stale' for fault_flags 3,
    'none' for 0; a number that is no value of an enum is shown as such ('7 (no control_mode)')."""
    return named.label(value)


def entity_paths(table: RigTable) -> dict[str, str]:
    """Entity path of every board field and HIL I/O object, by name (no Rerun import)."""
    return Tracer._entity_paths(table)


# --- Blueprints and opening saved traces ----------------------------------------------------
def load_blueprint(name: str) -> rrb.Blueprint:
    """The dashboards/ blueprint called `name` (FieldNameError with close matches otherwise)."""
    return resources.dashboards().blueprint(name)


def dashboard_fields(table: RigTable) -> list[str]:
    """Every board field a dashboard plots by name (`dashboards.joint.named_fields`)."""
    names: list[str] = resources.dashboards().named_fields(table)
    return names


def blueprint_names() -> tuple[str, ...]:
    return tuple(resources.dashboards().BLUEPRINTS)


def save_blueprint(name: str, path: str | Path) -> Path:
    """Write the blueprint `name` as a `.rbl` file for the hilrig application id."""
    path = Path(path)
    load_blueprint(name).save(APPLICATION_ID, path)
    return path


class ViewerProcess(subprocess.Popen[bytes]):
    """A viewer started by `open_trace`, in a process group of its own.

    `python -m rerun` is only a wrapper that runs the real binary and does not pass signals on,
    so `terminate()`, `kill()` and `send_signal()` signal the whole group: otherwise the binary
    would be left serving after its wrapper is gone. `url`: what to open in a browser (web=True).
    """

    url: str | None = None

    def send_signal(self, sig: int) -> None:
        self.poll()
        if self.returncode is None:  # once reaped, the group id may belong to someone else
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.pid, sig)


def web_viewer_url(web_port: int = DEFAULT_WEB_PORT, grpc_port: int = DEFAULT_GRPC_PORT) -> str:
    """The page to open for a trace served by `open_trace(..., web=True)`: the web viewer, told
    where the gRPC server with the data is (the browser connects to both ports)."""
    data = quote(f"rerun+http://127.0.0.1:{grpc_port}/proxy", safe="")
    return f"http://127.0.0.1:{web_port}/?url={data}"


def _check_port_free(port: int, what: str) -> None:
    # Rerun 0.41 does not fail on a port in use: it spins without serving anything. SO_REUSEADDR:
    # only a listener counts, not the TIME_WAIT connections of a viewer that just ended.
    with socket.socket() as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((VIEWER_BIND_ADDRESS, port))
        except OSError as error:
            raise OSError(f"{what} port {port} is in use ({error.strerror}): choose another one") from None


def open_trace(
    path: str | Path,
    blueprint: str = "overview",
    *,
    web: bool = False,
    web_port: int = DEFAULT_WEB_PORT,
    grpc_port: int = DEFAULT_GRPC_PORT,
    launch: bool = True,
) -> ViewerProcess | list[str]:
    """Open a saved trace in a native viewer (spawned), or serve it to the web viewer (web=True),
    with the named blueprint active.

    web=True serves the viewer page on 127.0.0.1:`web_port` and the recording from a gRPC
    server on 127.0.0.1:`grpc_port`; the page to open is printed and in `process.url`
    (`web_viewer_url`). No display is needed; from another machine, forward both ports
    (`ssh -L 9090:127.0.0.1:9090 -L 9876:127.0.0.1:9876 host`).

    Returns the viewer process (the caller owns it: `terminate()` ends the whole viewer);
    launch=False returns the command instead.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"no trace at {path}")
    rbl = Path(tempfile.mkdtemp(prefix="hilrig-blueprint-")) / f"{blueprint}.rbl"
    save_blueprint(blueprint, rbl)
    command = [sys.executable, "-m", "rerun"]
    if web:
        command += ["--web-viewer", "--web-viewer-port", str(web_port)]
    command += [str(path), str(rbl)]
    if web:
        # Without --port the data would go to 9876 whatever else listens there (spawn, compose).
        command += ["--port", str(grpc_port), "--bind", VIEWER_BIND_ADDRESS]
    if not launch:
        return command
    if web:
        _check_port_free(web_port, "web viewer")
        _check_port_free(grpc_port, "gRPC")
    process = ViewerProcess(command, process_group=0)
    if web:
        process.url = web_viewer_url(web_port, grpc_port)
        print(f"web viewer: open {process.url}", flush=True)
    return process


def wall_clock() -> float:
    """The `t` to pass in real-time mode (clock="wall"): Unix time in seconds."""
    return time.time()


__all__ = [
    "APPLICATION_ID",
    "BUS_EVENTS_PATH",
    "BUS_FRAMES_ROOT",
    "BUS_ROOT",
    "BUS_RPDOS_PER_CYCLE",
    "BUS_TPDOS_PER_CYCLE",
    "CYCLE_TIMELINE",
    "EMCY_PATH",
    "MODULES_ROOT",
    "NMT_PATH",
    "ROBOT_ROOT",
    "SDO_PATH",
    "SIM_TIME_TIMELINE",
    "TRUTH_QUANTITIES",
    "WALL_TIME_TIMELINE",
    "ChainTrace",
    "Severity",
    "SinkKind",
    "TraceSink",
    "Tracer",
    "ViewerProcess",
    "blueprint_names",
    "dashboard_fields",
    "entity_paths",
    "field_path",
    "frames_path",
    "kind_path",
    "link_path",
    "load_blueprint",
    "module_root",
    "open_trace",
    "save_blueprint",
    "truth_path",
    "web_viewer_url",
]
