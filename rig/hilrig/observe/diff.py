"""Two traces of the rig side by side: what changed since the last good run (`hilrig diff`).

Rerun compares no two recordings, so both are read back (`Trace.read`) and compared series by
series on the cycle timeline: a series' value at a cycle is its latest row at or before it (the
frame counts and parameters are logged as their changes), over the cycles both runs reached. A
value differs when |cand - base| > atol + rtol * max(|base|, |cand|); a text series (events)
differs at its first entry whose cycle or text is not the other run's. Of the series that part
at one cycle, the first named is the likeliest cause: what the rig sent before what the node
answered, then the truth, the bus counts, the events.

    result = compare(Trace.read(base), Trace.read(cand), Tolerance(atol=1e-9, rtol=1e-6))
    result.first   # Divergence(name="motor_duty_command", cycle=1312, base=0.214, cand=0.198, ...)
    write_comparison(result, base_trace, cand_trace, Path("out/diff.rrd"), blueprint)

`write_comparison` puts both runs in one recording, base under /base and candidate under /cand
(each at its own path below), cand - base under /diff, and one text entry per diverging series
at /diff/divergences on the cycle of its first divergence; the `diff` dashboard lays it out.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from fnmatch import fnmatch
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from hilrig.files import replacing
from hilrig.observe import streams
from hilrig.observe.paths import (
    BUS_ROOT,
    CYCLE_TIMELINE,
    DIFF_BASE_ROOT,
    DIFF_CAND_ROOT,
    DIFF_EVENTS_PATH,
    DIFF_ROOT,
    FIELDS_ROOT,
    HIL_INPUTS_ROOT,
    HIL_OUTPUTS_ROOT,
    MODULES_ROOT,
    SIM_TIME_TIMELINE,
    TRUTH_ROOT,
    WALL_CLOCK_SERIES,
)
from hilrig.observe.reader import Trace
from hilrig.observe.sinks import APPLICATION_ID

if TYPE_CHECKING:
    import rerun.blueprint as rrb

WALL_CLOCK_SECONDS = 1e6
"""A time beyond this is a real-time run's Unix timestamp, not simulation time."""


@dataclass(frozen=True)
class Tolerance:
    """How far two values may be apart and still count as equal."""

    atol: float = 1e-9
    rtol: float = 1e-6

    def exceeded(self, base: np.ndarray, cand: np.ndarray) -> np.ndarray:
        both_nan = np.isnan(base) & np.isnan(cand)
        with np.errstate(invalid="ignore"):
            apart = np.abs(cand - base) > self.atol + self.rtol * np.maximum(np.abs(base), np.abs(cand))
        return (apart | (np.isnan(base) != np.isnan(cand))) & ~both_nan


@dataclass(frozen=True)
class Divergence:
    """The first cycle a series differs beyond the tolerance, and its two values there."""

    path: str
    name: str
    cycle: int
    time_s: float | None
    base: float | str
    cand: float | str

    def __str__(self) -> str:
        when = f"cycle {self.cycle}" + (f" (t = {self.time_s:.3f} s)" if self.time_s is not None else "")
        if isinstance(self.base, str) or isinstance(self.cand, str):
            return f"{self.name} at {when}: {self.base!r} vs {self.cand!r}"
        return f"{self.name} at {when}: {self.base:.6g} vs {self.cand:.6g}"


@dataclass
class Comparison:
    """What `compare` found: every diverging series by its first divergence, earliest first."""

    compared: list[str]
    divergences: list[Divergence]
    only_base: list[str]
    only_cand: list[str]
    base_cycles: tuple[int, int] | None
    cand_cycles: tuple[int, int] | None
    period_s: float | None
    differences: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict, repr=False)
    """cand - base per compared scalar series: (cycles, differences)."""
    names: dict[str, str] = field(default_factory=dict, repr=False)
    """What a series is called where it is not by its path (a field's name)."""

    @property
    def first(self) -> Divergence | None:
        return self.divergences[0] if self.divergences else None

    @property
    def same(self) -> bool:
        return not self.divergences and not self.only_base and not self.only_cand

    def summary(self) -> list[str]:
        """The lines `hilrig diff` prints."""
        lines = [f"compared {len(self.compared)} series" + _span(self.base_cycles, self.cand_cycles)]
        if self.first is None:
            lines.append("no difference" if self.same else "no difference in the series both runs hold")
        else:
            lines.append(f"first divergence: {self.first}")
            later = self.divergences[1:]
            for divergence in later[:MORE_LISTED]:
                lines.append(f"  then {divergence}")
            if len(later) > MORE_LISTED:
                lines.append(f"  ... and {len(later) - MORE_LISTED} more series")
        if self.only_base:
            lines.append(f"only in base: {', '.join(self.only_base)}")
        if self.only_cand:
            lines.append(f"only in cand: {', '.join(self.only_cand)}")
        return lines


MORE_LISTED = 5
"""Diverging series listed after the first one; the recording has them all."""


def _span(base: tuple[int, int] | None, cand: tuple[int, int] | None) -> str:
    if base is None or cand is None:
        return ""
    if base == cand:
        return f" over cycles {base[0]}..{base[1]}"
    both = f"{max(base[0], cand[0])}..{min(base[1], cand[1])}"
    return f" over cycles {both} (base {base[0]}..{base[1]}, cand {cand[0]}..{cand[1]})"


def series_name(path: str, names: Mapping[str, str]) -> str:
    """A field's name for its path ("motor_duty_command"), the path itself for anything else."""
    return names.get(path, path)


def _period(trace: Trace) -> float | None:
    """Simulation seconds per cycle, from any series stamped on both timelines; None for a
    real-time run (wall-clock stamps) or a trace without one."""
    for path, cycles in trace.cycles.items():
        times = trace.times.get(path, [])
        if len(cycles) >= 2 and len(times) == len(cycles) and cycles[-1] != cycles[0]:
            if abs(times[-1]) > WALL_CLOCK_SECONDS:
                return None
            return (times[-1] - times[0]) / (cycles[-1] - cycles[0])
    return None


def _cycle_span(trace: Trace) -> tuple[int, int] | None:
    """The first and last cycle of the run's value series (events may come after its last cycle)."""
    ends = [(trace.cycles[p][0], trace.cycles[p][-1]) for p, values in trace.scalars.items() if values]
    if not ends:
        return None
    return min(e[0] for e in ends), max(e[1] for e in ends)


def _held(cycles: np.ndarray, values: np.ndarray, at: np.ndarray) -> np.ndarray:
    """A step series' value at each cycle of `at` (its latest row at or before), NaN before its first."""
    rows = np.searchsorted(cycles, at, side="right") - 1
    held = values[np.clip(rows, 0, None)].astype(float)
    held[rows < 0] = np.nan
    return held


def compare(
    base: Trace,
    cand: Trace,
    tolerance: Tolerance = Tolerance(),
    names: Mapping[str, str] | None = None,
    ignore: Sequence[str] = (),
) -> Comparison:
    """Every scalar and text series of both traces compared (see the module docstring); `names`
    says what to call a series (a field's name for its path), its path otherwise; a series whose
    path or name matches a glob of `ignore` is left out (events stamped by a wall clock), and so
    are the series a wall clock measured (`WALL_CLOCK_SERIES`: the TPDOs' delays after SYNC)."""
    names = dict(names or {})
    ignore = (*ignore, *WALL_CLOCK_SERIES)
    period = _period(base)
    if period is None:
        period = _period(cand)

    def time_of(cycle: int) -> float | None:
        return cycle * period if period is not None else None

    def kept(trace: Trace) -> set[str]:
        series = {p for p, v in trace.scalars.items() if v} | {p for p, v in trace.texts.items() if v}
        return {p for p in series if not any(fnmatch(p, g) or fnmatch(names.get(p, ""), g) for g in ignore)}

    base_series, cand_series = kept(base), kept(cand)
    common = sorted(base_series & cand_series)
    base_span, cand_span = _cycle_span(base), _cycle_span(cand)
    end_of_both = min(base_span[1], cand_span[1]) if base_span and cand_span else None
    divergences: list[Divergence] = []
    differences: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for path in common:
        name = series_name(path, names)
        if base.scalars.get(path) and cand.scalars.get(path):
            cb, vb = np.asarray(base.cycles[path]), np.asarray(base.scalars[path], dtype=float)
            cc, vc = np.asarray(cand.cycles[path]), np.asarray(cand.scalars[path], dtype=float)
            start, end = max(cb[0], cc[0]), min(cb[-1], cc[-1])
            grid = np.union1d(cb, cc)
            grid = grid[(grid >= start) & (grid <= end)]
            if grid.size == 0:
                continue
            held_base, held_cand = _held(cb, vb, grid), _held(cc, vc, grid)
            differences[path] = (grid, held_cand - held_base)
            apart = tolerance.exceeded(held_base, held_cand)
            if apart.any():
                i = int(np.argmax(apart))
                cycle = int(grid[i])
                divergences.append(
                    Divergence(path, name, cycle, time_of(cycle), float(held_base[i]), float(held_cand[i]))
                )
        elif base.texts.get(path) and cand.texts.get(path):
            found = _text_divergence(base, cand, path, end_of_both)
            if found is not None:
                cycle, base_text, cand_text = found
                divergences.append(Divergence(path, name, cycle, time_of(cycle), base_text, cand_text))
    divergences.sort(key=lambda d: (d.cycle, _cause_rank(d)))  # then in path order: sorted is stable
    return Comparison(
        compared=common,
        divergences=divergences,
        only_base=sorted(base_series - cand_series),
        only_cand=sorted(cand_series - base_series),
        base_cycles=base_span,
        cand_cycles=cand_span,
        period_s=period,
        differences=differences,
        names=names,
    )


_CAUSES_FIRST = (
    (f"{FIELDS_ROOT}/commands/", f"{FIELDS_ROOT}/parameters/", f"{HIL_INPUTS_ROOT}/"),
    (f"{FIELDS_ROOT}/", f"{HIL_OUTPUTS_ROOT}/"),
    (f"{TRUTH_ROOT}/",),
    (f"{BUS_ROOT}/",),
)
"""At one cycle, what the rig sent (commands, parameters, sensor inputs) before what the node
answered, then the plant's truth, the bus counts, and last the events they caused."""


def _cause_rank(divergence: Divergence) -> int:
    if isinstance(divergence.base, str) or isinstance(divergence.cand, str):
        return len(_CAUSES_FIRST)
    path = re.sub(rf"^{MODULES_ROOT}/\d+", "", divergence.path)  # a robot's module: its own paths
    ranks = (rank for rank, roots in enumerate(_CAUSES_FIRST) if path.startswith(roots))
    return next(ranks, len(_CAUSES_FIRST))


def _text_entries(trace: Trace, path: str) -> list[tuple[int, str]]:
    cycles = trace.cycles.get(path, [])
    texts = [text for text, _level in trace.texts[path]]
    if len(cycles) != len(texts):  # not stamped with cycles (a real-time run's wall clock only)
        return [(0, text) for text in texts]
    return sorted(zip(cycles, texts, strict=True), key=lambda entry: entry[0])


def _text_divergence(base: Trace, cand: Trace, path: str, end: int | None) -> tuple[int, str, str] | None:
    """The first entry where the two logs part, up to cycle `end`: (its cycle, base's text, cand's)."""
    base_entries, cand_entries = _text_entries(base, path), _text_entries(cand, path)
    if end is not None:
        base_entries = [entry for entry in base_entries if entry[0] <= end]
        cand_entries = [entry for entry in cand_entries if entry[0] <= end]
    for (cycle_b, text_b), (cycle_c, text_c) in zip(base_entries, cand_entries, strict=False):
        if (cycle_b, text_b) != (cycle_c, text_c):
            return min(cycle_b, cycle_c), text_b, text_c
    if len(base_entries) == len(cand_entries):
        return None
    longer = base_entries if len(base_entries) > len(cand_entries) else cand_entries
    cycle, text = longer[min(len(base_entries), len(cand_entries))]
    missing = "(no entry)"
    return (cycle, text, missing) if longer is base_entries else (cycle, missing, text)


def write_comparison(
    comparison: Comparison, base: Trace, cand: Trace, out: Path, blueprint: rrb.Blueprint | None = None
) -> Path:
    """One recording with both runs and their differences (see the module docstring), written
    whole: to a temporary file beside `out`, renamed when complete."""
    with replacing(out) as temporary:
        _write_recording(comparison, base, cand, temporary, f"diff-{out.stem}", blueprint)
    streams.release()  # the recording is let go of
    return out


def _write_recording(
    comparison: Comparison,
    base: Trace,
    cand: Trace,
    file: Path,
    recording_id: str,
    blueprint: rrb.Blueprint | None,
) -> None:
    import rerun as rr

    recording = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id)
    recording.set_sinks(rr.FileSink(str(file)))
    period = comparison.period_s

    def send(path: str, cycles: np.ndarray, values: np.ndarray, label: str) -> None:
        indexes = [rr.TimeColumn(CYCLE_TIMELINE, sequence=cycles)]
        if period is not None:
            indexes.append(rr.TimeColumn(SIM_TIME_TIMELINE, duration=cycles * period))
        recording.log(path, rr.SeriesLines(names=label), static=True)
        recording.send_columns(path, indexes=indexes, columns=rr.Scalars.columns(scalars=values))

    for path in comparison.compared:
        if not base.scalars.get(path) or not cand.scalars.get(path):
            continue
        name = series_name(path, comparison.names)
        for root, trace, run in ((DIFF_BASE_ROOT, base, "base"), (DIFF_CAND_ROOT, cand, "cand")):
            values = np.asarray(trace.scalars[path], dtype=float)
            send(root + path, np.asarray(trace.cycles[path]), values, f"{name} ({run})")
        grid, difference = comparison.differences[path]
        send(DIFF_ROOT + path, grid, difference, f"{name}: cand - base")
    for divergence in comparison.divergences:
        recording.set_time(CYCLE_TIMELINE, sequence=divergence.cycle)
        if divergence.time_s is not None:
            recording.set_time(SIM_TIME_TIMELINE, duration=divergence.time_s)
        level = rr.TextLogLevel.ERROR if divergence is comparison.first else rr.TextLogLevel.WARN
        prefix = "first divergence: " if divergence is comparison.first else ""
        recording.log(DIFF_EVENTS_PATH, rr.TextLog(f"{prefix}{divergence}", level=level))
    if blueprint is not None:
        streams.send_blueprint(recording, blueprint, make_active=False, make_default=True)
    recording.flush()
    recording.disconnect()


__all__ = ["Comparison", "Divergence", "Tolerance", "compare", "write_comparison"]
