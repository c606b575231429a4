"""The per-cycle record of a driver (`History`): what the node sent, what the rig sent, and the
plant's truth, stored per PDO as the bus carried it and assembled into series when asked for.
Apart from the drivers (`hilrig.engine.driver`) so that each stays one readable file.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from hilrig.plants.interface import Plant
from hilrig.table import unknown_name
from hilrig.wire.transport import ARRIVAL, ROW_CYCLE, PdoDirection, PdoLayout

Value = float | int
PdoRow = tuple[PdoLayout, tuple[Value, ...]]
"""One PDO of one cycle: its layout and the values it carried, in mapping order."""

_UNIT_SUFFIXES = ("_rad_s", "_rad", "_nm", "_a", "_c", "_ohm", "_v", "_m_s2", "_m", "_w", "_k")
"""The SI suffixes a truth name may be given without ("load_velocity" -> "load_velocity_rad_s")."""


def truth_aliases(names: Iterable[str]) -> dict[str, str]:
    """Short names without the unit suffix, of the truth quantities `names`."""
    aliases: dict[str, str] = {}
    for name in names:
        suffix = next((s for s in _UNIT_SUFFIXES if name.endswith(s)), None)
        if suffix is not None:
            aliases.setdefault(name[: -len(suffix)], name)
    return aliases


def resolve_truth_name(name: str, names: tuple[str, ...]) -> str:
    """`name` as one of the truth quantities `names` (itself, or by its short alias);
    FieldNameError-like with the close matches when it is neither."""
    if name in names:
        return name
    aliases = truth_aliases(names)
    if name in aliases:
        return aliases[name]
    raise unknown_name("ground-truth quantity", name, (*names, *aliases))


def records_dtype(formats: tuple[str, ...] | list[str]) -> np.dtype:
    """The numpy record type of a PDO's payload (`PdoLayout.formats`, field `v<i>` the i-th
    mapped object); ValueError when numpy would read a code at another size than struct packs it."""
    dtype = np.dtype({"names": [f"v{i}" for i in range(len(formats))], "formats": ["<" + f for f in formats]})
    if dtype.itemsize != struct.calcsize("<" + "".join(formats)):
        raise ValueError(f"PDO formats {''.join(formats)!r}: numpy and struct disagree on their size")
    return dtype


class _PdoRows:
    """Every cycle one PDO was exchanged in, with the payload it carried: two bytearrays, the
    cycles (`ROW_CYCLE` each) and the payloads back to back, as on the bus. An append is two
    copies of a few bytes, with no Python object kept per row (a million-cycle run holds some
    14 bytes per PDO and cycle, not a tuple of numbers); readers get numpy columns.

    Only ever appended to (a failed cycle's last row is taken back), so a count is a mark that
    stays valid. A writer appends the payload before the cycle and a reader counts cycles, so a
    reader on another thread never counts a row without its payload. Readers copy what they
    read (a slice): a live view on the bytearray would stop it from growing."""

    __slots__ = ("cycles", "data", "dtype", "layout", "names", "record", "width")

    def __init__(self, layout: PdoLayout) -> None:
        self.layout = layout
        self.names = layout.names
        if len(layout.formats) != len(layout.names):
            raise ValueError(f"{layout.label}: no codec, its rows cannot be stored")
        self.record = layout.codec
        self.width = layout.length
        self.dtype = records_dtype(layout.formats)
        self.cycles = bytearray()
        self.data = bytearray()

    @property
    def count(self) -> int:
        return len(self.cycles) // ROW_CYCLE.size

    def append(self, cycle: int, values: Iterable[Value]) -> None:
        self.data += self.record.pack(*values)
        self.cycles += ROW_CYCLE.pack(cycle)

    def last_cycle(self) -> int:
        return ROW_CYCLE.unpack_from(self.cycles, len(self.cycles) - ROW_CYCLE.size)[0]

    def drop_last(self) -> None:
        """Take the last row back (the cycle it belongs to failed)."""
        del self.cycles[-ROW_CYCLE.size :]
        del self.data[len(self.data) - self.width :]

    def last(self, position: int) -> tuple[int, Value]:
        """(cycle, value at `position`) of the last row (there is one)."""
        row = self.record.unpack_from(self.data, (self.count - 1) * self.width)
        return self.last_cycle(), row[position]

    def cycle_column(self, begin: int, end: int) -> np.ndarray:
        """The cycles of rows begin..end (int64)."""
        size = ROW_CYCLE.size
        return np.frombuffer(bytes(self.cycles[begin * size : end * size]), dtype=np.int64)

    def records(self, begin: int, end: int) -> np.ndarray:
        """Rows begin..end as a numpy record array (field `v<i>` is the i-th mapped value)."""
        return np.frombuffer(bytes(self.data[begin * self.width : end * self.width]), dtype=self.dtype)

    def matrix(self, begin: int, end: int) -> np.ndarray:
        """Rows begin..end as a float64 (rows x values) array."""
        records = self.records(begin, end)
        matrix = np.empty((len(records), len(self.names)), dtype=np.float64)
        for i, name in enumerate(self.dtype.names or ()):
            matrix[:, i] = records[name]
        return matrix

    def column(self, position: int) -> np.ndarray:
        """Every value at `position`, as the numbers they are: int64, float64 or bool."""
        return _widened(self.records(0, self.count)[f"v{position}"])


def _at_cycles(table: np.ndarray, cycles: np.ndarray) -> np.ndarray:
    """The second column of `table` ((cycle, value) rows, cycles ascending) at each of `cycles`,
    as float64; NaN where the table has no row of that cycle."""
    row = np.minimum(np.searchsorted(table[:, 0], cycles), len(table) - 1)
    return np.where(table[row, 0] == cycles, table[row, 1].astype(np.float64), np.nan)


def _widened(column: np.ndarray) -> np.ndarray:
    """A column of a PDO's own type (int16, float32, ...) as int64, float64 or bool: what
    arithmetic on a series expects, and exactly the numbers the bus carried."""
    if column.dtype.kind == "b":
        return column.astype(bool)
    return column.astype(np.int64 if column.dtype.kind in "iu" else np.float64)


class _Direction:
    """Rows by PDO layout, and where each name is found (a layout and a position)."""

    def __init__(self) -> None:
        self.rows: dict[PdoLayout, _PdoRows] = {}
        self.where: dict[str, list[tuple[_PdoRows, int]]] = {}
        self._by_identity: dict[int, tuple[PdoLayout, _PdoRows]] = {}

    def rows_of(self, pdo: PdoLayout) -> _PdoRows:
        # By identity first (an int key); equal layouts read again after a restart share rows.
        known = self._by_identity.get(id(pdo))
        if known is not None and known[0] is pdo:
            return known[1]
        rows = self.rows.get(pdo)
        if rows is None:
            rows = self.rows[pdo] = _PdoRows(pdo)
            for position, name in enumerate(pdo.names):
                self.where.setdefault(name, []).append((rows, position))
        self._by_identity[id(pdo)] = (pdo, rows)
        return rows

    def series(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Cycles and values of `name`, in cycle order, from every PDO that carried it."""
        places = [(rows, i) for rows, i in self.where.get(name, ()) if rows.count]
        if not places:
            return np.zeros(0, dtype=np.int64), np.zeros(0)
        # Counted once per PDO: the rig may append on while this reads (the tracer's thread).
        counts = [rows.count for rows, _ in places]
        cycles = [rows.cycle_column(0, count) for (rows, _), count in zip(places, counts, strict=True)]
        values = [
            _widened(rows.records(0, count)[f"v{i}"]) for (rows, i), count in zip(places, counts, strict=True)
        ]
        if len(places) == 1:
            return cycles[0], values[0]
        every_cycle = np.concatenate(cycles)
        order = np.argsort(every_cycle, kind="stable")
        return every_cycle[order], np.concatenate(values)[order]

    def has(self, name: str) -> bool:
        return any(rows.count for rows, _ in self.where.get(name, ()))

    def latest(self, name: str) -> tuple[int, Value] | None:
        best: tuple[int, Value] | None = None
        for rows, i in self.where.get(name, ()):
            if rows.count:
                last = rows.last(i)
                if best is None or last[0] >= best[0]:
                    best = last
        return best


@dataclass(frozen=True, slots=True)
class HistoryMark:
    """Where every PDO's rows and the truth ended at one moment (`History.mark`)."""

    rows: dict[_PdoRows, int]
    truth: int


HistoryBlock = tuple[PdoLayout, np.ndarray, np.ndarray]
"""(layout, cycles, values): one PDO's rows between two marks, the cycles (int64) and a float64
(rows x names) matrix; `layout.names` name its columns."""


def _forget(_state: object) -> None:
    """`History.record_truth` of a history that keeps nothing."""


class History:
    """Per-cycle record of what the node sent, what the rig sent, and the plant's truth.

    Stored per PDO as the bus carried it (`_PdoRows`: a cycle and a payload per row, appended
    in C for every TPDO a lockstep cycle decodes); a field's series is assembled when asked for.
    Times are cycle * period exactly: the start of the cycle whose SYNC the values belong to.
    Truth rows hold the plant's truth snapshot at that time (the one the cycle's sensor frame
    was sampled from); `plant` (`hilrig.plants.interface.Plant`) reads them into series.

    `keep=False` records nothing: no rows, no truth, so a run of any length holds the same
    memory. For a program that judges every cycle as it goes and asks for no series afterwards
    (the soak's million cycles); there is nothing to trace or to read back from it.
    """

    def __init__(self, period_us: int, *, keep: bool = True, plant: Plant | None = None) -> None:
        self.period_us = period_us
        self.bus_timeline: Any = None
        """A run on the timed bus: its `hilrig.engine.bustiming.BusTimeline` (what the trace
        plots beside the cycles); None on the ideal bus."""
        self.plant = plant
        self.keep = keep
        """Whether rows and truth are recorded (a driver then appends its rows: `row_store`)."""
        self._received = _Direction()
        self._sent = _Direction()
        self._truth: list[object] = []
        self._arrivals: dict[PdoLayout, bytearray] = {}
        """Per TPDO, (cycle, CLOCK_MONOTONIC ns) of each arrival (`ARRIVAL`), as the exchange
        appends them (`arrival_store`)."""
        self.sync_store: bytearray | None = bytearray() if keep else None
        """Where a lockstep driver appends (cycle, CLOCK_MONOTONIC ns) of each cycle's SYNC as it
        was sent (`transport.ARRIVAL`): what `delays_of` measures from; None when nothing is kept.
        The driver appends itself, as the exchange appends arrivals: a call per cycle less."""
        self.record_truth: Callable[[object], None] = self._truth.append if keep else _forget
        """Record the plant state of the next cycle (every cycle: the list's own append)."""

    def time_of(self, cycle: int) -> float:
        return cycle * self.period_us / 1e6

    def _times(self, cycles: Iterable[int] | np.ndarray) -> np.ndarray:
        if not isinstance(cycles, np.ndarray):
            cycles = np.fromiter(cycles, dtype=np.int64)
        return cycles * self.period_us / 1e6

    @property
    def cycles(self) -> int:
        return len(self._truth)

    def layouts(self) -> list[PdoLayout]:
        """Every PDO layout with rows here (received, then sent), with or without a row yet."""
        return [*self._received.rows, *self._sent.rows]

    def mark(self) -> HistoryMark:
        """Where everything recorded so far ends: what an observer has taken so far (the tracer
        takes whole batches of columns from here instead of copying every cycle's values)."""
        rows = {r: r.count for d in (self._received, self._sent) for r in d.rows.values()}
        return HistoryMark(rows, len(self._truth))

    def blocks_between(self, start: HistoryMark, end: HistoryMark) -> list[HistoryBlock]:
        """What was recorded after `start` up to `end`, PDO by PDO, as columns (safe from
        another thread while the rig records on: rows are only appended to)."""
        blocks = []
        for rows, stop in end.rows.items():
            begin = start.rows.get(rows, 0)
            if stop > begin:
                blocks.append((rows.layout, rows.cycle_column(begin, stop), rows.matrix(begin, stop)))
        return blocks

    def truth_between(self, start: HistoryMark, end: HistoryMark) -> tuple[range, list[object]]:
        """The cycles and truth snapshots recorded after `start` up to `end` (one per cycle)."""
        return range(start.truth, end.truth), self._truth[start.truth : end.truth]

    def times_of(self, cycles: Iterable[int] | np.ndarray) -> np.ndarray:
        """The times of these cycles [s], as `time_of` gives them."""
        return self._times(cycles)

    def record_rows(self, cycle: int, received: Iterable[PdoRow], sent: Iterable[PdoRow]) -> None:
        """Rows of one cycle from their values (what the lockstep driver does from the frames)."""
        if not self.keep:
            return
        for direction, pdo_rows in ((self._received, received), (self._sent, sent)):
            for pdo, values in pdo_rows:
                direction.rows_of(pdo).append(cycle, values)

    def row_store(self, pdo: PdoLayout) -> tuple[bytearray, bytearray]:
        """(cycles, payloads) of `pdo`'s rows (received for a TPDO, sent for an RPDO), for a
        driver that appends to them every cycle while the history `keep`s: the payload as on
        the bus, then the cycle (`ROW_CYCLE`), as `transport.append_row` and the C exchange do."""
        direction = self._sent if pdo.direction is PdoDirection.RPDO else self._received
        rows = direction.rows_of(pdo)
        return rows.cycles, rows.data

    def take_back(self, pdo: PdoLayout, cycle: int) -> None:
        """Drop `pdo`'s last row if it is `cycle`'s (that cycle failed after the row went in)."""
        direction = self._sent if pdo.direction is PdoDirection.RPDO else self._received
        rows = direction.rows_of(pdo)
        if rows.count and rows.last_cycle() == cycle:
            rows.drop_last()
        arrivals = self._arrivals.get(pdo)
        if arrivals and ARRIVAL.unpack_from(arrivals, len(arrivals) - ARRIVAL.size)[0] == cycle:
            del arrivals[-ARRIVAL.size :]

    def arrival_store(self, pdo: PdoLayout) -> bytearray:
        """Where the exchange appends (cycle, CLOCK_MONOTONIC ns) of each of `pdo`'s arrivals
        (`transport.ARRIVAL`), beside its rows (`row_store`)."""
        return self._arrivals.setdefault(pdo, bytearray())

    def delays_of(self, pdo: PdoLayout, cycles: np.ndarray) -> np.ndarray | None:
        """`pdo`'s delay after its cycle's SYNC [s] in each of `cycles` (cycles it arrived in), by
        the exchange's clock; NaN where either time is not known; None when none is kept."""
        arrivals = self._arrivals.get(pdo)
        if not arrivals or not self.sync_store or not len(cycles):
            return None
        arrived = np.frombuffer(bytes(arrivals), dtype=np.int64).reshape(-1, 2)
        synced = np.frombuffer(bytes(self.sync_store), dtype=np.int64).reshape(-1, 2)
        return (_at_cycles(arrived, cycles) - _at_cycles(synced, cycles)) / 1e9

    def has_received(self, name: str) -> bool:
        return self._received.has(name)

    def has_sent(self, name: str) -> bool:
        return self._sent.has(name)

    def received(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """(t, values) of every cycle a TPDO carried `name`."""
        cycles, values = self._received.series(name)
        return self._times(cycles), values

    def sent(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """(t, values) of every cycle the rig sent `name` in an RPDO."""
        cycles, values = self._sent.series(name)
        return self._times(cycles), values

    def latest_received(self, name: str) -> Value:
        latest = self._received.latest(name)
        if latest is None:
            raise KeyError(name)
        return latest[1]

    def truth_name(self, name: str) -> str:
        """`name` as one of the plant's truth quantities (itself or its short alias)."""
        if self.plant is None:
            raise ValueError("this history has no plant, so no truth")
        return resolve_truth_name(name, self.plant.truth_fields)

    def truth(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """(t, values) of a ground-truth quantity of the plant (`Plant.truth_fields`, or a name
        without its unit suffix)."""
        attribute = self.truth_name(name)
        assert self.plant is not None
        states = self._truth[:]  # the rig may append on while this reads (the tracer's thread)
        values = self.plant.truth_matrix(states)[:, self.plant.truth_fields.index(attribute)]
        return self._times(range(len(states))), values


__all__ = [
    "History",
    "HistoryBlock",
    "HistoryMark",
    "PdoRow",
    "Value",
    "resolve_truth_name",
    "truth_aliases",
]
