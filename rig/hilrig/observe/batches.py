"""How the tracer's rows become Rerun data: the spans of a Rig's History and the rows of replayed
cycles pivoted into one numpy column per entity and sent as Arrow record batches (one per group
of series over the same cycles, which Rerun splits into a chunk per entity), the static names of
the series, and the changes-only series (commands, parameters, frame counts).

`RecordBatches` is the tracer's sending half: `hilrig.observe.tracer.Tracer` collects and hands
over, these methods run on its sender thread.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from boardproto.table import BitSet, ValueEnum
from hilrig.engine.driver import CycleResult, History, HistoryMark
from hilrig.observe.busmeter import BusMeter, Measured, PdoSpec
from hilrig.observe.paths import (
    BUS_EVENTS_PATH,
    BUS_LOAD_PATH,
    BUS_RPDOS_PER_CYCLE,
    BUS_TPDOS_PER_CYCLE,
    CYCLE_TIMELINE,
    FIELDS_ROOT,
    MODULES_ROOT,
    SIM_TIME_TIMELINE,
    TIMED_BACKLOG_PATH,
    TIMED_LATE_PATH,
    TIMED_LOAD_PATH,
    TRUTH_ROOT,
    WALL_TIME_TIMELINE,
    BusProblem,
    delay_path,
    frames_path,
    label_path,
    plant_truth_path,
    problem_path,
    truth_unit,
)
from hilrig.observe.sinks import Severity
from hilrig.wire.transport import PdoDirection, PdoLayout

if TYPE_CHECKING:
    import rerun as rr

Value = float | int
Clock = Literal["simulation", "wall"]
_BUS_TOTALS = ((BUS_TPDOS_PER_CYCLE, PdoDirection.TPDO), (BUS_RPDOS_PER_CYCLE, PdoDirection.RPDO))
"""The frames per cycle of each direction: the series and the direction it sums."""


@dataclass(frozen=True, slots=True)
class _CycleRow:
    cycle: int
    time_s: float
    groups: tuple[tuple[Sequence[str], Sequence[Value]], ...]
    """(names, values) pairs: one per PDO, or one per dict given to `log_cycle`."""
    truth: object | None  # None: real time without physics


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



def value_name(named: ValueEnum | BitSet, value: float) -> str:
    """'velocity' for control_mode 1, 'motor_encoder_stale|output_encoder_stale' for fault_flags 3,
    'none' for 0; a number that is no value of an enum is shown as such ('7 (no control_mode)')."""
    return named.label(value)


class RecordBatches:
    """The sending half of the tracer (its state is made by `Tracer.__init__`)."""

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
        plant = self._plant
        if truth and plant is not None:  # the truth too, when the rig has a plant, and its parameters
            quantities = (*plant.truth_fields, *plant.truth_parameters())
            series += [(self.root + plant_truth_path(quantity), None, False) for quantity in quantities]
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
        if states:  # the truth parameters' changes go with the frame counts' (mostly the same rows)
            parameters = self._truth_parameter_series(len(every_cycle))
            self._send_frames(frames, every_cycle, times, also=parameters)
            self._measure_span(frames, every_cycle, times)

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
        states = [batch[i].truth for i in with_truth]
        self._send_parts(parts, also=self._truth_row_sets(truth_cycles, truth_times, states))
        self._send_truth_parameters(truth_cycles, truth_times)

        results = [row for row in batch if isinstance(row, CycleResult)]
        if results:
            cycles_of: dict[PdoLayout, list[int]] = {}
            for result in results:
                for pdo, _ in (*result.received_rows, *result.sent_rows):
                    cycles_of.setdefault(pdo, []).append(result.cycle)
            frames = [(pdo, np.asarray(c, dtype=np.int64)) for pdo, c in cycles_of.items()]
            every_cycle = np.asarray([r.cycle for r in results], dtype=np.int64)
            result_times = np.asarray([r.time_s for r in results])
            self._send_frames(frames, every_cycle, result_times)
            self._measure_span(frames, every_cycle, result_times)

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
        a fixed cost (the batch's schema read, its chunks handed to Rerun's batcher), many times
        higher in the emulated VM, which would otherwise be most of what a batch costs."""
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

    def _measure_span(
        self, blocks: Sequence[tuple[PdoLayout, np.ndarray]], every_cycle: np.ndarray, times: np.ndarray
    ) -> None:
        """The bus measurements of consecutive cycles: each one's SYNC and the PDO frames it
        carried (`hilrig.observe.busmeter`), at the cycle's time; with a History, the TPDOs'
        delays after the SYNC as the exchange measured them (`History.delays_of`). One board only
        (a robot's modules share one bus: no module sees it whole)."""
        if self._module is not None or not len(every_cycle):
            return
        tpdo, history = PdoDirection.TPDO, self._history
        if self._bus_meter is None:
            self._bus_meter = BusMeter({}, bitrate=self.bitrate)
        meter = self._bus_meter
        meter.pdos.update(  # the node's PDOs as last read (a restarted node's may be others)
            (layout.cob_id, PdoSpec(
                f"{layout.direction.value}{layout.number}", layout.length, layout.direction is tpdo,
                layout.transmission_type,
            ))
            for layout in (history.layouts() if history is not None else [pdo for pdo, _ in blocks])
            if layout.enabled and layout.cob_id
        )

        def delays(layout: PdoLayout, cycles: np.ndarray) -> np.ndarray | None:
            if history is None or layout.direction is not tpdo:
                return None
            return history.delays_of(layout, cycles)

        frames = [
            (layout.cob_id, cycles, delays(layout, cycles))
            for layout, cycles in blocks
            if layout.enabled and layout.cob_id
        ]
        meter.span(every_cycle, times, frames)
        self._send_bus(meter.take())
        if history is not None and history.bus_timeline is not None:
            self._send_timed_bus(history.bus_timeline, every_cycle, times)

    def _send_timed_bus(self, timeline: Any, every_cycle: np.ndarray, times: np.ndarray) -> None:
        """The timed bus's per-cycle load (% of its bit rate, at most 100), backlog and late frames
        (`hilrig.engine.bustiming.BusTimeline`) for the cycles of a span it has."""
        first, count = timeline.first_cycle, len(timeline.load)
        inside = (every_cycle >= first) & (every_cycle < first + count)
        if not inside.any():
            return
        cycles = every_cycle[inside]
        lo, hi = int(cycles[0]) - first, int(cycles[-1]) - first + 1
        offsets = cycles - first - lo
        # Slices of the arrays are copies: the run appends to them while the trace reads.
        series = [
            (TIMED_LOAD_PATH, 100.0 * np.asarray(timeline.load[lo:hi], dtype=np.float64)[offsets]),
            (TIMED_BACKLOG_PATH, np.asarray(timeline.backlog_frames[lo:hi], dtype=np.float64)[offsets]),
            (TIMED_LATE_PATH, np.asarray(timeline.late_frames[lo:hi], dtype=np.float64)[offsets]),
        ]
        root = self.root
        self._name_many(
            [
                (root + TIMED_LOAD_PATH, "timed bus load [% of its bit rate]", False),
                (root + TIMED_BACKLOG_PATH, "frames waiting for a later cycle", True),
                (root + TIMED_LATE_PATH, "frames delivered late", True),
            ]
        )
        self._send_group(cycles.tolist(), times[inside].tolist(), [(root + path, v) for path, v in series])

    def _send_bus(self, measured: Measured) -> None:
        """Bus measurements (`hilrig.observe.busmeter`) into the recording: the load and the counts
        per window, each TPDO's delays, each problem as a text log entry."""
        root = self.root
        if measured.window_cycles:
            series = [(root + path, values) for path, values in measured.series()]
            self._name_many(
                [(root + BUS_LOAD_PATH, f"bus load [% of {self.bitrate / 1e6:g} Mbit/s]", False)]
                + [(root + problem_path(p), f"{p.value.replace('_', ' ')} [frames]", True)
                   for p in BusProblem]
            )
            self._send_group(measured.window_cycles, measured.window_times, series)
        for label, (cycles, times, delays) in measured.delays.items():
            path = root + delay_path(label)
            self._name_many([(path, f"{label} after SYNC [ms]", False)])
            self._send_group(cycles, times, [(path, np.asarray(delays, dtype=np.float64))])
        for event in measured.events:
            level = Severity.ERROR if event.problem is BusProblem.ERROR_FRAME else Severity.WARN
            self._send_text(root + BUS_EVENTS_PATH, event.text, level, t=event.t, cycle=event.cycle)

    def _end_bus(self) -> None:
        """The end of the recording: the lockstep meter's open window too."""
        if self._bus_meter is not None:
            self._send_bus(self._bus_meter.take(final=True))

    def _bus_totals_series(self) -> list[tuple[str, str, bool]]:
        """(path, series name, counts) of the frames per cycle of each direction (`_name_many`)."""
        return [
            (self.root + path, f"{direction.value}s per cycle [frames]", True)
            for path, direction in _BUS_TOTALS
        ]

    def _truth_row_sets(
        self, cycles: np.ndarray, times: np.ndarray, states: Sequence[object]
    ) -> list[_RowSet]:
        """The truth's series over these snapshots of the plant's, as the row set `_send_parts`
        sends with the PDOs' (none without states, or before the rig gave its plant)."""
        with self._lock:
            plant = self._plant
        if not states or plant is None:
            return []
        matrix = plant.truth_matrix(states)
        series = [
            (self.root + plant_truth_path(quantity), matrix[:, column])
            for column, quantity in enumerate(plant.truth_fields)
        ]
        return [(cycles, times, series)]

    def _send_truth_parameters(self, cycles: np.ndarray, times: np.ndarray) -> None:
        """The plant's truth parameters over these cycles (as their changes)."""
        if len(cycles):
            self._send_changes(cycles, times, self._truth_parameter_series(len(cycles)))

    def _truth_parameter_series(self, count: int) -> list[tuple[str, np.ndarray]]:
        """The plant's truth parameters over `count` cycles, as (path, values) (none before the
        rig gave its plant)."""
        with self._lock:
            plant = self._plant
        if plant is None:
            return []
        return [
            (self.root + plant_truth_path(name), np.full(count, value))
            for name, value in plant.truth_parameters().items()
        ]

    def _send_group(
        self, cycles: Sequence[int], times: Sequence[float], series: Sequence[tuple[str, np.ndarray]]
    ) -> None:
        """Entities over the same rows (`_send_row_sets`): one Arrow record batch, which Rerun
        splits into one chunk per entity, each as `send_columns` would make it. One call for the
        group instead of one per entity: in the emulated VM the Python of each call is dear. An
        entity not named yet gets its default name first."""
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
            if self._module is not None:
                fields.append(_component_field(pa, path, self._line_colors, pa.uint32()))
                arrays.append(pa.array([self._module_colour(path)], pa.uint32()))
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

    def _series_name(self, path: str) -> str:
        name = path.rsplit("/", 1)[-1]
        module = f"module {self._module} " if self._module is not None else ""
        if path.removeprefix(self.root).startswith(TRUTH_ROOT):
            return f"{module}true {name} [{truth_unit(name)}]"
        every = self._polled.get(name)
        polled = f" (SDO, every {every} cycles)" if every is not None else ""
        return f"{module}{name} [{self.table.entry(name).unit}]{polled}"

    def _module_colour(self, path: str) -> int:
        """A robot module's colour (RGBA): what the rig commands in a lighter shade of it and the
        plant's truth in a darker one, so one plot of every module's commanded and measured angle
        (or measured and true torque) tells them apart."""
        assert self._module is not None
        rgb = MODULE_COLOURS[(self._module - 1) % len(MODULE_COLOURS)]
        own = path.removeprefix(self.root)
        if own.startswith(f"{FIELDS_ROOT}/commands/"):
            rgb = tuple(round(c + (255 - c) * SHADE) for c in rgb)  # type: ignore[assignment]
        elif own.startswith(TRUTH_ROOT):
            rgb = tuple(round(c * (1 - SHADE)) for c in rgb)  # type: ignore[assignment]
        red, green, blue = rgb
        return (red << 24) | (green << 16) | (blue << 8) | 0xFF


MODULE_COLOURS: tuple[tuple[int, int, int], ...] = (
    (31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75),
    (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207), (57, 59, 121), (140, 109, 49),
    (132, 60, 57), (99, 121, 57), (123, 65, 115), (0, 0, 0),
)
"""One colour per module of a robot (node id 1 the first): sixteen that stay apart."""
SHADE = 0.5
"""How far towards white a module's commanded series is drawn, towards black its truth."""


def module_of(root: str) -> int | None:
    """3 for a tracer rooted at /modules/3; None for one board's."""
    prefix = MODULES_ROOT + "/"
    if root.startswith(prefix) and root[len(prefix):].isdigit():
        return int(root[len(prefix):])
    return None



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
    """Rows of numbers as a float64 (rows x width) array. Through one flat iterator: faster than
    np.asarray on a list of tuples, which inspects every tuple, and this is most of what a batch
    costs on our side."""
    if count is None:
        count = len(rows)  # type: ignore[arg-type]
    flat = np.fromiter(itertools.chain.from_iterable(rows), dtype=np.float64, count=count * width)
    return flat.reshape(count, width)


def _frames_series_name(pdo: PdoLayout) -> str:
    """'TPDO3 (0x390) [frames]': the series of a PDO's frames per cycle."""
    return f"{pdo.label} [frames]"
