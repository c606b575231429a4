"""A bus with a bit rate, for lockstep: which of a cycle's frames the real bus carries within
the cycle's time, in CAN arbitration order, and which wait for a later cycle.

A virtual CAN bus carries any load; a real one carries `bitrate * period` bits per cycle. Each
cycle the lockstep driver hands `TimedBus.window` every frame of the cycle (its RPDOs, its SYNC,
the node's due TPDOs, heartbeats, EMCYs, SDO frames) and the ones still waiting from earlier
cycles (the backlog):

- every frame counts its worst-case length (`framebits.frame_bits_worst_case`: the data length
  alone, with the most stuff bits the frame can have, and the intermission). Worst case because
  the schedule is made before the cycle's frames exist: whether an RPDO goes out this cycle must
  be known before it is sent, and the node's TPDOs are known only by their mapping's length;
- the frames go on the bus as arbitration orders them: lowest identifier first (the dominant
  bits win), frames of one identifier oldest first, each frame whole (CAN does not preempt): a
  frame that starts before the cycle's time is up is carried in this cycle, even if it ends
  after, and its overhang delays the next cycle's first frame;
- a frame that does not start in time waits (the backlog) and is delivered, to the node or to
  the plant, in the first later cycle that has room for it;
- one frame of an identifier waits at a time: a newer one replaces it (a CAN controller's
  transmit mailbox per PDO, its data updated by the next cycle), and the older one is never
  sent (`BusWindow.replaced`); except `queued` frames (an SDO transfer's, EMCYs), which are a
  sequence and all go out in turn, oldest first. So the backlog holds at most one frame per identifier, and a
  mapping that overloads the bus every cycle starves its lowest-priority frames for good, as
  the real bus would.

No randomness: the same frames give the same schedule, every run.

    bus = TimedBus(bitrate=1_000_000, period_us=1000)
    w = bus.window(cycle, [BusFrame(0x80, 1, cycle), BusFrame(0x190, 5, cycle), ...])
    w.delivered, w.backlog, w.load
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

from hilrig.wire.framebits import MAX_DATA_BYTES, frame_bits_worst_case

STANDARD_BITRATES: tuple[int, ...] = (125_000, 250_000, 500_000, 1_000_000)
"""Classic CAN bit rates in bit/s: what `hilrig bus-load` reports by default and what a robot's
"which bit rate does it need" answer chooses from."""
IDEAL = "ideal"
"""The option's spelling for no bit rate: every frame in its cycle (the virtual bus as it is)."""


def bitrate_text(bitrate: int) -> str:
    """'1 Mbit/s', '500 kbit/s', '83.3 kbit/s'."""
    if bitrate >= 1_000_000:
        return f"{bitrate / 1e6:g} Mbit/s"
    return f"{bitrate / 1e3:g} kbit/s"


WORST_CASE_BITS = tuple(frame_bits_worst_case(dlc) for dlc in range(MAX_DATA_BYTES + 1))
"""A classic frame's worst-case bits by its data length (`framebits`), looked up per frame."""


class BusFrame:
    """One frame for the timed bus: its identifier, data length, the cycle it was queued in and
    what the caller needs to deliver it (`payload`, anything; filled in later for a TPDO whose
    data comes after the schedule). `queued`: one of a sequence of frames of its identifier
    that all go out in turn (an SDO transfer's requests or answers, EMCYs), not a mailbox that a
    newer frame replaces."""

    __slots__ = ("bits", "cob_id", "dlc", "origin", "payload", "queued")

    def __init__(self, cob_id: int, dlc: int, origin: int, payload: Any = None, queued: bool = False) -> None:
        self.cob_id = cob_id
        self.dlc = dlc
        self.origin = origin
        self.payload = payload
        self.queued = queued
        self.bits = WORST_CASE_BITS[dlc]

    def __repr__(self) -> str:
        return f"BusFrame(0x{self.cob_id:03X}, {self.dlc}, cycle {self.origin})"


@dataclass(frozen=True, slots=True)
class BusWindow:
    """What one cycle's time on the bus carried."""

    cycle: int
    delivered: tuple[BusFrame, ...]
    """The frames carried this cycle, in bus order (late ones have `origin` < `cycle`)."""
    backlog: tuple[BusFrame, ...]
    """The frames still waiting after it, in arbitration order."""
    busy_bits: float
    """Bits of this cycle's time the bus was busy (the overhang from the cycle before included,
    this cycle's own overhang not): at most `window_bits`."""
    window_bits: float
    replaced: tuple[BusFrame, ...] = ()
    """Frames that were still waiting when a newer one of their identifier came: never sent."""

    @property
    def load(self) -> float:
        """Share of the cycle's time the bus was busy, 0..1 (a real bus cannot exceed 1)."""
        return self.busy_bits / self.window_bits

    @property
    def backlog_bits(self) -> int:
        return sum(f.bits for f in self.backlog)

    def late(self) -> list[tuple[BusFrame, int]]:
        """(frame, cycles late) of each frame delivered after its own cycle."""
        return [(f, self.cycle - f.origin) for f in self.delivered if f.origin < self.cycle]


class TimedBus:
    """The bus of one lockstep run at `bitrate` bit/s with a control period of `period_us`."""

    def __init__(self, bitrate: int, period_us: int) -> None:
        if bitrate <= 0 or period_us <= 0:
            raise ValueError(f"bit rate and period: expected > 0, got {bitrate} and {period_us}")
        self.bitrate = bitrate
        self.period_us = period_us
        self.window_bits = bitrate * period_us / 1e6
        """Bits the bus carries in one cycle's time."""
        self.backlog: list[BusFrame] = []
        self.overhang = 0.0
        """Bits of the last frame of the cycle before that ran into this cycle's time."""
        self._fits: dict[object, int | None] = {}

    def window(self, cycle: int, frames: Iterable[BusFrame]) -> BusWindow:
        """Cycle `cycle`'s time on the bus: the backlog and `frames` (this cycle's) in arbitration
        order; what does not start in time is the new backlog."""
        queue = self.backlog
        lost: list[BusFrame] = []
        if queue:
            waiting = {f.cob_id: f for f in queue if not f.queued}
            for frame in frames:
                older = None if frame.queued else waiting.pop(frame.cob_id, None)
                if older is not None:
                    lost.append(older)
                queue.append(frame)
            if lost:
                gone = {id(f) for f in lost}
                queue = [f for f in queue if id(f) not in gone]
        else:
            queue.extend(frames)
        queue.sort(key=_arbitration)
        window_bits = self.window_bits
        t = self.overhang
        delivered: list[BusFrame] = []
        waiting: list[BusFrame] = []
        seen: set[int] = set()
        for frame in queue:
            if t >= window_bits or frame.cob_id in seen:
                waiting.append(frame)
                continue
            if not frame.queued:
                seen.add(frame.cob_id)
            delivered.append(frame)
            t += frame.bits
        self.overhang = max(0.0, t - window_bits)
        self.backlog = waiting
        return BusWindow(
            cycle, tuple(delivered), tuple(waiting), min(t, window_bits), window_bits, tuple(lost)
        )

    def bits_if_all_fit(self, frames: Iterable[tuple[int, int]]) -> int | None:
        """The bits of frames of these (COB-ID, data length) when they all fit one cycle with
        nothing waiting (the cycle's schedule is then all of them in their own cycle, whatever
        their order); else None. What a driver checks before it builds a steady cycle's frames
        (`fits_cached` remembers the answer per cycle shape)."""
        if self.backlog or self.overhang:
            return None
        pairs = list(frames)
        ids = {cob_id for cob_id, _ in pairs}
        total = sum(WORST_CASE_BITS[dlc] for _, dlc in pairs)
        return total if len(ids) == len(pairs) and total <= self.window_bits else None

    def fits_cached(self, shape: object, frames: Callable[[], Iterable[tuple[int, int]]]) -> int | None:
        """`bits_if_all_fit(frames())`, remembered per `shape` (anything hashable that tells the
        cycle's frames apart: the due TPDOs, the RPDOs' headers): a steady cycle costs a lookup."""
        if self.backlog or self.overhang:
            return None
        try:
            return self._fits[shape]
        except KeyError:
            bits = self._fits[shape] = self.bits_if_all_fit(frames())
            return bits


BUS_PROPERTY = "hil_bus"
"""The JUnit property (pytest's user property) naming the bus of each lockstep run of a scenario:
its bit rate (`bitrate_text`) or `ideal_label(why)`; the pytest plugin's terminal summary and
tools/test-summary.py count the scenarios of each (`bus_summary`)."""
_IDEAL_PREFIX = f"{IDEAL}: "


def ideal_label(why: str) -> str:
    """BUS_PROPERTY's value for a run on the ideal bus: 'ideal: why'."""
    return _IDEAL_PREFIX + why


def bus_summary(scenarios: Iterable[Sequence[str]]) -> list[str]:
    """From each scenario's BUS_PROPERTY values (a scenario of several runs counts once per
    bus): '12 scenarios on the timed bus (1 Mbit/s 11, 250 kbit/s 1)', then '3 on the ideal
    bus, ...:' and one line per reason, most first. Nothing when no scenario named its bus."""
    timed: dict[str, int] = {}
    ideal: dict[str, int] = {}
    for labels in scenarios:
        for label in dict.fromkeys(labels):
            if label.startswith(_IDEAL_PREFIX):
                why = label.removeprefix(_IDEAL_PREFIX)
                ideal[why] = ideal.get(why, 0) + 1
            else:
                timed[label] = timed.get(label, 0) + 1
    lines = []
    if timed:
        counts = ", ".join(f"{label} {n}" for label, n in sorted(timed.items()))
        lines.append(f"{sum(timed.values())} scenarios on the timed bus ({counts})")
    if ideal:
        lines.append(f"{sum(ideal.values())} scenarios on the ideal bus, which carries any load:")
        lines += [f"    {n} {why}" for why, n in sorted(ideal.items(), key=lambda item: (-item[1], item[0]))]
    return lines


def _arbitration(frame: BusFrame) -> tuple[int, int]:
    return frame.cob_id, frame.origin


def needed_bitrate(
    cycles: Sequence[Sequence[tuple[int, int]]], period_us: int, bitrates: Sequence[int] = STANDARD_BITRATES
) -> tuple[int | None, dict[int, int]]:
    """The lowest of `bitrates` at which every frame of `cycles` (each cycle's (COB-ID, data
    length) frames, one after the other) is delivered in its own cycle, or None; and for each
    bit rate the number of frames that were not (late, or still waiting at the end)."""
    late: dict[int, int] = {}
    for bitrate in sorted(bitrates):
        bus = TimedBus(bitrate, period_us)
        late[bitrate] = 0
        for n, frames in enumerate(cycles):
            w = bus.window(n, [BusFrame(cob_id, dlc, n) for cob_id, dlc in frames])
            late[bitrate] += len(frames) - sum(1 for f in w.delivered if f.origin == n)
    fitting = [b for b in sorted(bitrates) if late[b] == 0]
    return (fitting[0] if fitting else None), late


__all__ = [
    "BUS_PROPERTY",
    "IDEAL",
    "STANDARD_BITRATES",
    "WORST_CASE_BITS",
    "BusFrame",
    "BusWindow",
    "TimedBus",
    "bitrate_text",
    "bus_summary",
    "ideal_label",
    "needed_bitrate",
]
