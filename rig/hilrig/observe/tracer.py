"""Tracing to Rerun: every field the rig receives or sends, every cycle, next to the physics' truth.

    tracer = Tracer(TraceSink.rrd(scenario_dir / "trace.rrd"), table, blueprint="overview")
    with Rig(bus, params=params, tracer=tracer) as rig:
        rig.run(seconds=1.0)
    tracer.close()                                   # flushes; the .rrd is complete after this
    open_trace(scenario_dir / "trace.rrd", blueprint="tuning")   # native viewer, or web=True


The entity paths and timelines are `hilrig.observe.paths`'; the sinks `hilrig.observe.sinks`.

Off the hot path: as a `RigObserver` the tracer follows the rig's `History` (`on_history`), which
already keeps every PDO's values per cycle, so a traced cycle costs a count and no Rerun call.
Every `batch_cycles` cycles (and, for a live viewer, at least once a second) the span since the
last batch (two `History.mark`s) goes to a background thread that sends it as Arrow record
batches (`hilrig.observe.batches`). Rows given by `log_cycle` (a replayed log) are pivoted the
same way. Nothing is ever dropped and the lockstep loop never waits for Rerun (`make bench`
measures a traced Rig against an untraced one). `import rerun` is slow in the emulated VM, so it
happens only when a Tracer is made.
"""

from __future__ import annotations

import functools
import queue
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Self

import numpy as np

from boardproto import Field, Kind
from boardproto.cia301 import NmtState
from boardproto.table import BitSet, ValueEnum
from hilrig import resources
from hilrig.engine.driver import CycleResult, History, HistoryMark
from hilrig.engine.observers import RigObserver
from hilrig.observe import streams
from hilrig.observe.batches import Clock, RecordBatches, Value, _Batch, _CycleRow, _HistorySpan, module_of
from hilrig.observe.blueprints import load_blueprint
from hilrig.observe.busmeter import TRACE_BITRATE, BusMeter, Measured
from hilrig.observe.chain import ChainTrace
from hilrig.observe.paths import (
    BOARD_PROPERTY,
    CYCLE_TIMELINE,
    EMCY_PATH,
    GENERATED_DASHBOARD,
    NMT_PATH,
    SDO_PATH,
    SIM_TIME_TIMELINE,
    WALL_TIME_TIMELINE,
    entity_paths,
    module_root,
    plant_truth_path,
)
from hilrig.observe.sinks import (
    APPLICATION_ID,
    DEFAULT_GRPC_PORT,
    DEFAULT_WEB_PORT,
    Severity,
    SinkKind,
    TraceSink,
    default_latency,
    web_viewer_url,
)
from hilrig.plants.interface import Plant
from hilrig.table import RigTable
from hilrig.wire.node import EmcyRecord
from hilrig.wire.transport import PdoLayout

if TYPE_CHECKING:
    import rerun.blueprint as rrb

    from hilrig.engine.robot import ChainModel

DEFAULT_BATCH_CYCLES = 5000
"""Cycles collected before one batch is pivoted and sent (5 s of simulation at 1 kHz). Each
batch has a fixed cost in Rerun per entity whatever its length (a chunk, its schema, its place
in the file's footer), so large batches are what makes a traced run cost little."""
SETTLE_TIMEOUT_S = 5.0
"""How long `Tracer.settle` (at the rig's start, once its series are named) waits for Rerun to
take what was sent so far; past it the start goes on and the rest is written beside the run."""


DEFAULT_BLUEPRINT = "overview"
"""The dashboard a trace of the demo joint opens with; another board's opens with the one
generated from its table and plant (GENERATED_DASHBOARD)."""


class Tracer(RecordBatches, RigObserver):
    """Logs the rig's cycles, NMT changes, EMCYs and SDO aborts to Rerun.

    sink: one `TraceSink` or several. table: names -> kinds and units (RigTable.load()).
    blueprint: name in `dashboards.BLUEPRINTS` sent with the trace, built for `table` (None: the
    viewer's own); the default, the demo joint's overview, only with the demo joint's table, the
    generated one (GENERATED_DASHBOARD, sent once the plant and the node's PDOs are known) with
    another's. Every trace also records its table and that name (BOARD_PROPERTY), which is how
    `hilrig view` knows the board of a trace.
    batch_cycles: cycles per batch at most. max_latency_s: also hand a batch over when this much
    wall time passed since the last one (default: LIVE_LATENCY_S with a live sink, never for .rrd
    files alone). background: pivot and send batches in a thread (True) or
    inline on the caller's thread at each batch boundary (False). clock: "simulation" (lockstep:
    `sim_time` timeline) or "wall" (real-time mode: `t` is Unix time, `wall_time` timeline).
    bitrate: what the bus load is a share of (the virtual bus has none of its own).

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
        blueprint: str | None = DEFAULT_BLUEPRINT,
        batch_cycles: int = DEFAULT_BATCH_CYCLES,
        max_latency_s: float | None = None,
        background: bool = True,
        clock: Clock = "simulation",
        recording_name: str | None = None,
        root: str = "",
        share: Tracer | None = None,
        bitrate: int = TRACE_BITRATE,
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
        self._line_colors = rr.SeriesLines.descriptor_colors()
        self.table = table
        self.sinks: tuple[TraceSink, ...] = (sink,) if isinstance(sink, TraceSink) else tuple(sink)
        if not self.sinks and share is None:
            raise ValueError("Tracer needs at least one sink")
        if root and (not root.startswith("/") or root.endswith("/")):
            raise ValueError(f"root: expected an entity path like /modules/3, got {root!r}")
        self.root = root
        """Prefix of every entity path this tracer writes ("" for one board; a robot's modules
        each have their own, e.g. /modules/3, on one recording)."""
        self._module = module_of(root)
        """A robot's module: its series are named "module 3 ..." and drawn in its own colour."""
        self.batch_cycles = batch_cycles
        self.bitrate = bitrate
        """The bit rate the bus load is a share of (`hilrig.observe.busmeter`)."""
        self._bus_meter: BusMeter | None = None  # a lockstep run's, made with its first span
        self.max_latency_s = max_latency_s if max_latency_s is not None else default_latency(self.sinks)
        self._next_hand_over = time.monotonic() + (self.max_latency_s or 0.0)
        self.clock: Clock = clock
        self.time_timeline = SIM_TIME_TIMELINE if clock == "simulation" else WALL_TIME_TIMELINE
        self.web_url: str | None = None
        """The page of the served web viewer (with the data's address), when a web sink is used."""
        self._handed_over_cycles = 0  # cycles logged and handed to the sender (cycles_logged)
        self._look_at = 1  # on_cycle looks further once this many cycles are pending
        self._plant: Plant | None = None
        self._paths = {name: root + path for name, path in entity_paths(table).items()}
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
        self._lock = threading.Lock()  # guards the swap of _pending, and _plant (event threads)
        self._closed = False
        self._error: BaseException | None = None

        self._owns_recording = share is None
        self._live_urls: list[str] = []  # the gRPC addresses of the live sinks (send_blueprint)
        # A live sink's recording is live (`streams.live`) from here until close() disconnects it.
        self._live = self._owns_recording and any(s.kind is not SinkKind.RRD for s in self.sinks)
        if share is not None:  # another tracer's recording and sinks (a robot's module)
            self.recording = share.recording
            self.sinks = share.sinks
            self._live_urls = share._live_urls
        else:
            self.recording = rr.RecordingStream(APPLICATION_ID, recording_id=recording_name)
            if self._live:
                streams.go_live()
        try:
            if self._owns_recording:
                self._attach_sinks()
            if blueprint == DEFAULT_BLUEPRINT and not resources.is_default_table(table.board.source):
                blueprint = GENERATED_DASHBOARD  # another board's trace
            if self._owns_recording:
                self._send_board(blueprint)
            # The generated dashboard names the plant's truth: sent when the rig configures (or at close).
            self._generated_pending = blueprint == GENERATED_DASHBOARD
            if blueprint is not None and not self._generated_pending:
                self.send_blueprint(load_blueprint(blueprint, table))
        except BaseException:  # no tracer, so no close(): the live stream ends here
            if self._live:
                self.recording.disconnect()
                streams.end_live()
            raise

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

    def _send_board(self, dashboard: str | None) -> None:
        """The board property (BOARD_PROPERTY): the table's text, its file's name, the dashboard."""
        source = self.table.board.source
        try:
            text = Path(source).read_text(encoding="utf-8")
        except OSError:  # a table not read from a file: the trace says nothing of its board
            return
        values: dict[str, str] = {"table": text, "table_name": Path(source).name}
        if dashboard is not None:
            values["dashboard"] = dashboard
        self._rr.send_property(BOARD_PROPERTY, self._rr.AnyValues(**values), recording=self.recording)

    def _send_generated(self, *, truth: bool) -> None:
        """The generated dashboard, once: for the table, with the plant's truth when it is traced."""
        if not self._generated_pending:
            return
        self._generated_pending = False
        plant = self._plant
        quantities = [*plant.truth_fields, *plant.truth_parameters()] if truth and plant is not None else []
        self.send_blueprint(load_blueprint(GENERATED_DASHBOARD, self.table, truth=quantities))

    # --- What the Rig calls -----------------------------------------------------------------
    def log_plant(self, plant: Plant) -> None:
        """The rig's plant: its truth is traced from its snapshots (`Plant.truth_matrix`), and
        its truth parameters (`Plant.truth_parameters`: a spring constant) beside it every
        cycle from now on, as steps."""
        with self._lock:
            self._plant = plant
            self._held |= {self.root + plant_truth_path(name) for name in plant.truth_parameters()}

    def log_cycle(
        self,
        cycle: int,
        t: float,
        received: Mapping[str, Value],
        sent: Mapping[str, Value],
        truth: object | None,
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
    def on_plant(self, plant: Plant) -> None:
        self.log_plant(plant)

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
        if not self._closed:
            self._send_generated(truth=truth)
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
        self._send_text(path, text, level, t=t, cycle=cycle)

    def log_bus(self, measured: Measured) -> None:
        """Bus measurements of frames the caller metered (`hilrig.observe.busmeter`: a replayed
        log's), sent in order with the batches."""
        self.submit(functools.partial(self._send_bus, measured))

    def _send_text(self, path: str, text: str, level: Severity, *, t: float, cycle: int | None) -> None:
        rr = self._rr
        indexes = [self._time_column([t])]
        if cycle is not None:
            indexes.insert(0, rr.TimeColumn(CYCLE_TIMELINE, sequence=[cycle]))
        self.recording.send_columns(
            path, indexes=indexes, columns=rr.TextLog.columns(text=[text], level=[level.value])
        )

    def close(self) -> None:
        """Send what is pending, stop the sender thread, flush every sink and let go of the
        recording: once the robot's module tracers are closed too, what Rerun kept of it (its
        threads) is freed (`streams.release`). Idempotent.

        A served web viewer keeps serving the data until this process exits.
        """
        if self._closed:
            return
        self._send_generated(truth=self._plant is not None)
        self._hand_over()
        self.submit(self._end_bus)  # the bus's last, open load window
        self._closed = True
        self._look_at = 0  # a cycle after this is an error (`_counted`)
        if self._worker is not None and self._queue is not None:
            self._queue.put(None)
            self._worker.join()
        self.recording.flush()
        if self._owns_recording:
            if any(s.kind is SinkKind.WEB for s in self.sinks):
                streams.keep_serving(self.recording)  # its files are complete all the same
            else:
                self.recording.disconnect()
            if self._live:
                streams.end_live()
        del self.recording  # a closed tracer sends nothing; the sweep frees what nothing holds
        if self._owns_recording:
            streams.release()
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
        streams.send_blueprint(self.recording, blueprint, make_active=False, make_default=True)
        rr = self._rr
        for url in self._live_urls:
            with streams.live():
                stream = rr.RecordingStream(
                    APPLICATION_ID, recording_id=self.recording.get_recording_id(), send_properties=False
                )
                stream.connect_grpc(url)
                try:
                    streams.send_blueprint(stream, blueprint, make_active=True, make_default=True)
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

    def module_tracer(self, node_id: int, table: RigTable | None = None) -> Tracer:
        """A tracer for module `node_id` of a robot: its paths under /modules/<id>, on this
        tracer's recording and sinks (close it before this one); `table`: the module's board's
        when it is another board than the robot's (the head on a snake)."""
        return Tracer(
            (),
            table if table is not None else self.table,
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

    def path_of(self, name: str) -> str:
        """Entity path of a board field or HIL I/O object (FieldNameError with close matches)."""
        self.table.entry(name)
        return self._paths[name]


def wall_clock() -> float:
    """The `t` to pass in real-time mode (clock="wall"): Unix time in seconds."""
    return time.time()
