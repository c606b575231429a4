"""Bus measurements for a trace: the load per 10 ms window in % of the bit rate, each TPDO's delay
after its SYNC, and the TPDOs late, missing or malformed and the error frames, as events and as
counts. What the bus dashboard plots, made the same way from a live lockstep run (the tracer,
from its History's frames) and from a bus log (`hilrig replay LOG --trace`, frame by frame).

    meter = BusMeter(tpdos, bitrate=1_000_000)
    meter.frame(t, cycle, cob_id, data_bytes)          # every frame of a log, in time order
    measured = meter.take()                            # what is complete so far, for the tracer

Load: each frame's bits as `hilrig.wire.framebits` counts them with worst-case stuffing (as
`hilrig bus-load` budgets), summed per window of `WINDOW_S`, over the window's bits at the bit
rate. A window is stamped at its start (the cycle and time of its first frame); the bus's
counts go with it: the late, missing and malformed frames and the error frames seen up to the
window's end (each also an event, with its cycle).

A TPDO's delay is its time after the latest SYNC: from a log, the frames' timestamps; from a
lockstep run, the exchange's own clock (given with the frame). A cyclic TPDO (transmission
type n in 1..240) that has come before is missing at the SYNC where more than n cycles passed
since it last came; one that comes twice between two SYNCs came late (it is the last cycle's).
A frame on a PDO's COB-ID of another length than the mapping's is malformed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from boardproto.cia301 import LAST_SYNCHRONOUS_TYPE, SYNC_COB_ID
from hilrig.observe.paths import BUS_LOAD_PATH, BusProblem, problem_path
from hilrig.wire.framebits import frame_bits

WINDOW_S = 0.010
"""The bus load's window: 10 ms."""
TRACE_BITRATE = 1_000_000
"""The bit rate a trace's bus load is a share of, unless told (the virtual bus has none; 1 Mbit/s
is CANopen's fastest and what a 1 kHz exchange needs)."""
SYNC_BYTES = 1  # the SYNC counter


def load_percent(bits: float | np.ndarray, seconds: float, bitrate: int) -> float | np.ndarray:
    """`bits` sent in `seconds` as a share of the bit rate, in %."""
    return 100.0 * bits / (seconds * bitrate)


@dataclass(frozen=True)
class PdoSpec:
    """What the meter knows of one PDO: its label ('TPDO1'), data bytes, and for a TPDO its
    transmission type (whether it is cyclic, and every how many SYNCs)."""

    label: str
    length: int
    tpdo: bool
    transmission_type: int = 255

    @property
    def every(self) -> int | None:
        """SYNCs between two of it when cyclic; None otherwise (acyclic, event-driven, an RPDO)."""
        if self.tpdo and 1 <= self.transmission_type <= LAST_SYNCHRONOUS_TYPE:
            return self.transmission_type
        return None


@dataclass
class BusEvent:
    cycle: int
    t: float
    text: str
    problem: BusProblem


@dataclass
class Measured:
    """What `BusMeter.take` hands over: per window (cycle, time, load %, counts by problem), per
    TPDO label its delays (cycles, times, ms), and the events."""

    window_cycles: list[int] = field(default_factory=list)
    window_times: list[float] = field(default_factory=list)
    load: list[float] = field(default_factory=list)
    counts: dict[BusProblem, list[int]] = field(default_factory=lambda: {p: [] for p in BusProblem})
    delays: dict[str, tuple[list[int], list[float], list[float]]] = field(default_factory=dict)
    events: list[BusEvent] = field(default_factory=list)

    def series(self) -> list[tuple[str, np.ndarray]]:
        """The windows' series as (path, values): the load and each count."""
        return [(BUS_LOAD_PATH, np.asarray(self.load, dtype=np.float64))] + [
            (problem_path(p), np.asarray(v, dtype=np.float64)) for p, v in self.counts.items()
        ]


class BusMeter:
    """The measurements of a stream of frames in time order (see the module). `pdos`: COB-ID ->
    PdoSpec of the node's PDOs in use."""

    def __init__(
        self, pdos: Mapping[int, PdoSpec], *, bitrate: int = TRACE_BITRATE, window_s: float = WINDOW_S
    ) -> None:
        if bitrate <= 0 or window_s <= 0:
            raise ValueError(f"bitrate and window: expected > 0, got {bitrate} and {window_s}")
        self.pdos = dict(pdos)
        self.bitrate = bitrate
        self.window_s = window_s
        self.totals = dict.fromkeys(BusProblem, 0)
        self._first_t: float | None = None
        self._window = -1  # index of the open window
        self._window_start: tuple[int, float] = (0, 0.0)
        self._bits = 0
        self._sync_t: float | None = None
        self._cycle = -1  # of the latest SYNC
        self._seen: set[int] = set()  # cyclic TPDOs since the latest SYNC
        self._last: dict[int, int] = {}  # cyclic TPDO -> the cycle it last came in
        self._uncounted: list[tuple[int, BusProblem]] = []  # (cycle, problem) not in `totals` yet
        self._out = Measured()

    def frame(
        self,
        t: float,
        cycle: int,
        cob_id: int,
        data_bytes: int,
        *,
        error: bool = False,
        delay_s: float | None = None,
    ) -> None:
        """One frame at time `t` of `cycle` (the latest SYNC's). `delay_s`: a TPDO's delay after
        its SYNC as measured by whoever took it (default: `t` minus the latest SYNC's time)."""
        self._advance(t, cycle)
        if error:
            self._problem(BusProblem.ERROR_FRAME, cycle, t, f"error frame at t = {t:.6f} s")
            return
        self._bits += frame_bits(data_bytes, worst_case=True)
        if cob_id == SYNC_COB_ID:
            self._sync(t, cycle)
            return
        spec = self.pdos.get(cob_id)
        if spec is None:
            return
        if data_bytes != spec.length:
            self._problem(
                BusProblem.MALFORMED, cycle, t,
                f"{spec.label} (0x{cob_id:03X}) malformed: {data_bytes} bytes, its mapping has {spec.length}",
            )
            return
        if not spec.tpdo:
            return
        if spec.every is not None:
            if cob_id in self._seen:
                text = f"{spec.label} late: a second one after SYNC {cycle}"
                self._problem(BusProblem.LATE, cycle, t, text)
            self._seen.add(cob_id)
            self._last[cob_id] = cycle
        if delay_s is None:
            if self._sync_t is None:
                return
            delay_s = t - self._sync_t
        cycles, times, delays = self._out.delays.setdefault(spec.label, ([], [], []))
        cycles.append(cycle)
        times.append(t)
        delays.append(delay_s * 1e3)

    def span(
        self,
        cycles: np.ndarray,
        times: np.ndarray,
        frames: Sequence[tuple[int, np.ndarray, np.ndarray | None]],
    ) -> None:
        """A span of a lockstep run at once, in numpy: consecutive `cycles` at `times`, a SYNC
        each, and per PDO (COB-ID) the cycles it went over the bus in (RPDOs sent, TPDOs
        received), with each TPDO's delays after its SYNC as the exchange measured them (NaN: not
        known). A cycle's frames count at the cycle's time. The exchange refuses a TPDO late or
        malformed (the rig's own events say so): only missing ones are seen here."""
        if not len(cycles):
            return
        first, last, count = int(cycles[0]), int(cycles[-1]), len(cycles)
        bits = np.full(count, frame_bits(SYNC_BYTES, worst_case=True), dtype=np.int64)
        for cob_id, at, delays in frames:
            spec = self.pdos.get(cob_id)
            if spec is None or not len(at):
                continue
            offsets = np.asarray(at, dtype=np.int64) - first
            inside = (offsets >= 0) & (offsets < count)
            bits += np.bincount(offsets[inside], minlength=count) * frame_bits(spec.length, worst_case=True)
            if not spec.tpdo:
                continue
            if delays is not None:
                known = inside & ~np.isnan(delays)
                kept = self._out.delays.setdefault(spec.label, ([], [], []))
                kept[0].extend(np.asarray(at)[known].tolist())
                kept[1].extend(times[offsets[known]].tolist())
                kept[2].extend((delays[known] * 1e3).tolist())
            if spec.every is not None:
                self._missing(cob_id, spec, np.asarray(at)[inside].tolist(), last, times, first)
        if self._first_t is None:
            self._first_t = float(times[0])
        window = np.floor((times - self._first_t) / self.window_s + 1e-9).astype(np.int64)
        starts = np.concatenate(([0], np.flatnonzero(np.diff(window)) + 1))
        for start, total in zip(starts.tolist(), np.add.reduceat(bits, starts).tolist(), strict=True):
            if window[start] != self._window:
                if self._window >= 0:
                    self._close_window(int(cycles[start]))
                self._window = int(window[start])
                self._window_start = (int(cycles[start]), self._first_t + self._window * self.window_s)
            self._bits += total

    def _missing(
        self, cob_id: int, spec: PdoSpec, came: list[int], last_cycle: int, times: np.ndarray, first: int
    ) -> None:
        """A cyclic TPDO's slots without it, from the cycles it came in up to `last_cycle`."""
        every = spec.every
        assert every is not None
        last = self._last.get(cob_id)
        for cycle in [*came, last_cycle + every + 1]:  # the end: slots up to the span's last cycle
            if last is not None:
                while cycle - last > every and last + every <= last_cycle:
                    last += every
                    at = min(max(last - first, 0), len(times) - 1)
                    text = f"{spec.label} missing at SYNC {last}"
                    self._problem(BusProblem.MISSING, last, float(times[at]), text)
            if cycle <= last_cycle:
                last = cycle
        if last is not None:
            self._last[cob_id] = last

    def _sync(self, t: float, cycle: int) -> None:
        for cob_id, last in self._last.items():  # the cycles that ended without a cyclic TPDO
            every = self.pdos[cob_id].every
            assert every is not None
            while cycle - last > every:
                last += every
                self._problem(
                    BusProblem.MISSING, last, t, f"{self.pdos[cob_id].label} missing at SYNC {last}"
                )
            self._last[cob_id] = last
        self._sync_t, self._cycle = t, cycle
        self._seen.clear()

    def _problem(self, problem: BusProblem, cycle: int, t: float, text: str) -> None:
        """Counted (in `totals`) when the window before `cycle`'s next one closes."""
        self._uncounted.append((cycle, problem))
        self._out.events.append(BusEvent(cycle, t, text, problem))

    def _advance(self, t: float, cycle: int) -> None:
        """Close the windows that end at or before `t` (empty ones too: a quiet bus is 0 %)."""
        if self._first_t is None:
            self._first_t = t
        window = math.floor((t - self._first_t) / self.window_s + 1e-9)
        if window == self._window:
            return
        if self._window >= 0:
            self._close_window(cycle)
            for empty in range(self._window + 1, window):
                self._window_start = (cycle, self._first_t + empty * self.window_s)
                self._close_window(cycle)
        self._window = window
        self._window_start = (cycle, self._first_t + window * self.window_s)

    def _close_window(self, next_cycle: int | None) -> None:
        """The open window into the output, with the problems of cycles before `next_cycle` (the
        next window's first; None: all) counted."""
        counted = [(c, p) for c, p in self._uncounted if next_cycle is None or c < next_cycle]
        for _, problem in counted:
            self.totals[problem] += 1
        if counted:
            left = next_cycle if next_cycle is not None else math.inf
            self._uncounted = [(c, p) for c, p in self._uncounted if c >= left]
        out = self._out
        cycle, start = self._window_start
        out.window_cycles.append(cycle)
        out.window_times.append(start)
        out.load.append(float(load_percent(self._bits, self.window_s, self.bitrate)))
        for problem, count in self.totals.items():
            out.counts[problem].append(count)
        self._bits = 0

    def take(self, *, final: bool = False) -> Measured:
        """The complete windows, the delays and the events since the last take; `final`: the open
        window too (the end of the recording)."""
        if final and self._window >= 0:
            self._close_window(None)
            self._window = -1
            self._first_t = None
        out, self._out = self._out, Measured()
        return out


__all__ = [
    "TRACE_BITRATE",
    "WINDOW_S",
    "BusEvent",
    "BusMeter",
    "Measured",
    "PdoSpec",
    "load_percent",
]
