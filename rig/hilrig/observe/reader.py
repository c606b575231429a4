"""Read a trace the rig wrote (`.rrd`) back with Rerun's own reader (`rerun.chunk.RrdReader`):
per entity, the cycle and simulation-time stamps, the scalar values, the text log entries with
their levels, and the series names. For tests and for people post-processing a recording:

    trace = Trace.read(Path("out/scenarios/<test>/trace.rrd"))
    trace.scalars["/fields/virtual_sensors/motor_velocity"]   # one value per logged cycle
    trace.at_cycles("/bus/frames/TPDO8", range(100))           # a step series at every cycle
    trace.board.table()                                        # the board's table it recorded
"""

from __future__ import annotations

import bisect
from collections import defaultdict
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from hilrig.observe.paths import BOARD_PROPERTY

if TYPE_CHECKING:
    from hilrig.table import RigTable

LINEAR_INTERPOLATION = 1
"""rerun.components.InterpolationMode.Linear: a series' default."""
MIN_MAX_AGGREGATION = 5
"""rerun.components.AggregationPolicy.MinMax."""


@dataclass(frozen=True)
class TraceBoard:
    """Which board a trace is, as its tracer recorded it (`hilrig.observe.layout.BOARD_PROPERTY`)."""

    table_text: str
    table_name: str
    dashboard: str | None
    """The dashboard the trace opens with (None: the tracer named none)."""

    def table(self) -> RigTable:
        """The recorded table (TableError if it does not load)."""
        from hilrig.table import RigTable

        return RigTable.loads(self.table_text, self.table_name)

    @classmethod
    def from_columns(cls, columns: dict[str, list[Any]]) -> TraceBoard | None:
        """The property's static row (`_columns` of its chunk); None without a table in it."""

        def first(name: str) -> str | None:
            values = columns.get(name)
            cell = values[0] if values else None
            return str(cell[0]) if cell else None

        text = first("table")
        if text is None:
            return None
        return cls(text, first("table_name") or "board.toml", first("dashboard") or None)


def board_property_path() -> str:
    """'/__properties/board': where Rerun keeps the tracer's board property."""
    import rerun as rr

    return f"{rr.RECORDING_PROPERTIES_PATH}/{BOARD_PROPERTY}"


def read_board(path: Path) -> TraceBoard | None:
    """The board property of the trace at `path`, reading only the static chunks at its start
    (what the tracer sends before any data); None for a trace that records none."""
    import rerun as rr

    where = board_property_path()
    for chunk in rr.chunk.RrdReader(path).stream():
        if not chunk.is_static:
            break
        if chunk.entity_path == where:
            return TraceBoard.from_columns(_columns(chunk.to_record_batch()))
    return None


@dataclass
class Trace:
    """What a .rrd holds, per entity: cycle, sim_time and the values (or texts and levels)."""

    cycles: dict[str, list[int]] = field(default_factory=lambda: defaultdict(list))
    times: dict[str, list[float]] = field(default_factory=lambda: defaultdict(list))
    scalars: dict[str, list[float]] = field(default_factory=lambda: defaultdict(list))
    texts: dict[str, list[tuple[str, str]]] = field(default_factory=lambda: defaultdict(list))
    series_names: dict[str, str] = field(default_factory=dict)
    stepped: set[str] = field(default_factory=set)
    """Series drawn as steps (a value held until the next sample), not as straight lines."""
    banded: set[str] = field(default_factory=set)
    """Series drawn zoomed out as the band between their least and greatest value."""
    rows: dict[str, int] = field(default_factory=lambda: defaultdict(int))
    """Rows on a timeline per entity, whatever they hold (scalars, texts, 3D transforms)."""
    blueprints: int = 0
    board: TraceBoard | None = None
    """Which board the trace is (its table, its dashboard), when its tracer recorded it."""

    @classmethod
    def read(cls, path: Path) -> Trace:
        """Every chunk of `path`, its columns taken whole (Arrow to NumPy, one list per series at
        the end): a scenario reads a trace of hundreds of thousands of values in the emulated VM,
        where a Python object per value made by Arrow was most of the read."""
        import pyarrow.compute as pc
        import rerun as rr

        reader = rr.chunk.RrdReader(path)
        trace = cls(blueprints=len(reader.blueprints()))
        cycles: dict[str, list[np.ndarray]] = defaultdict(list)
        times: dict[str, list[np.ndarray]] = defaultdict(list)
        scalars: dict[str, list[np.ndarray]] = defaultdict(list)
        board_path = board_property_path()
        for chunk in reader.stream():
            batch = chunk.to_record_batch()
            path_ = chunk.entity_path
            if chunk.is_static:
                if path_ == board_path:
                    trace.board = TraceBoard.from_columns(_columns(batch))
                else:
                    trace._read_static(path_, _columns(batch))
                continue
            trace.rows[path_] += chunk.num_rows
            columns = dict(zip(batch.schema.names, batch.columns, strict=True))
            if "cycle" in columns:
                cycles[path_].append(columns["cycle"].to_numpy(zero_copy_only=False))
            for timeline in ("sim_time", "wall_time"):  # wall_time: Unix seconds
                if timeline in columns:
                    times[path_].append(_nanoseconds(columns[timeline]).to_numpy(zero_copy_only=False) / 1e9)
            if "Scalars:scalars" in columns:
                first = pc.list_element(columns["Scalars:scalars"], 0)
                scalars[path_].append(first.to_numpy(zero_copy_only=False))
            if "TextLog:text" in columns:
                texts = zip(
                    columns["TextLog:text"].to_pylist(), columns["TextLog:level"].to_pylist(), strict=True
                )
                trace.texts[path_] += [(text[0], level[0]) for text, level in texts]
        joined = {path_: np.concatenate(parts) for path_, parts in cycles.items()}
        joined_times = {path_: np.concatenate(parts) for path_, parts in times.items()}
        for path_, parts in scalars.items():  # chunks of one entity may come in any order
            order = np.argsort(joined[path_], kind="stable")
            joined[path_] = joined[path_][order]
            joined_times[path_] = joined_times[path_][order]
            trace.scalars[path_] = np.concatenate(parts)[order].tolist()
        for path_, values in joined.items():
            trace.cycles[path_] = values.tolist()
        for path_, values in joined_times.items():
            trace.times[path_] = values.tolist()
        return trace

    def _read_static(self, path: str, columns: dict[str, list[Any]]) -> None:
        """A series' name and how it is drawn, from its static chunk."""
        if "SeriesLines:names" in columns:
            self.series_names[path] = columns["SeriesLines:names"][0][0]
        modes = columns.get("SeriesLines:interpolation_mode")
        if modes and modes[0] and modes[0][0] != LINEAR_INTERPOLATION:
            self.stepped.add(path)
        policies = columns.get("SeriesLines:aggregation_policy")
        if policies and policies[0] and policies[0][0] == MIN_MAX_AGGREGATION:
            self.banded.add(path)

    def at_cycles(self, path: str, cycles: Iterable[int]) -> list[float]:
        """A step series' value at each of `cycles`: its latest row at or before the cycle (a
        series sent as its changes, like the frame counts). KeyError before its first row."""
        logged, values = self.cycles[path], self.scalars[path]
        found: list[float] = []
        for cycle in cycles:
            row = bisect.bisect_right(logged, cycle) - 1
            if row < 0:
                raise KeyError(f"{path}: no row at or before cycle {cycle}")
            found.append(values[row])
        return found


def _nanoseconds(column: Any) -> Any:
    """Timestamps (the wall_time timeline) and durations (sim_time) as integer nanoseconds,
    since Python's datetime and timedelta cannot hold nanoseconds (a real-time run stamps its
    ticks to the nanosecond)."""
    import pyarrow as pa

    if pa.types.is_timestamp(column.type):
        return column.cast(pa.timestamp("ns")).cast(pa.int64())
    if pa.types.is_duration(column.type):
        return column.cast(pa.duration("ns")).cast(pa.int64())
    return column


def _columns(batch: Any) -> dict[str, list[Any]]:
    """A record batch as lists, times as integer nanoseconds (`_nanoseconds`)."""
    return {
        name: _nanoseconds(column).to_pylist()
        for name, column in zip(batch.schema.names, batch.columns, strict=True)
    }


def timeline_end(path: Path, timeline: str) -> int | None:
    """The last time a trace logged on `timeline` (cycles for "cycle", nanoseconds for the
    time timelines); None when nothing was logged on it. Reads only that column of each chunk."""
    import pyarrow as pa
    import pyarrow.compute as pc
    import rerun as rr

    end: int | None = None
    for chunk in rr.chunk.RrdReader(path).stream():
        if chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        if timeline not in batch.schema.names:
            continue
        column = batch.column(timeline)
        if pa.types.is_timestamp(column.type) or pa.types.is_duration(column.type):
            column = column.cast(pa.int64())  # the chunk's own unit: nanoseconds in the tracer's
        latest = pc.max(column).as_py()
        if latest is not None and (end is None or latest > end):
            end = int(latest)
    return end
