"""Two bus logs compared frame by frame: `hilrig diff BASE.log CAND.blf`.

The logs may be of any format the rig reads (`hilrig.session.logformats`); a frame is its
identifier (standard or extended), its kind (data, remote, error), its length and its bytes. Times
are ignored by default (two runs of one scenario never share a wall clock); compared, they are
either each frame's time since its log's first frame, or the absolute time (a log and its
conversion), within a tolerance. The comparison stops at the first frame that differs.
"""

from __future__ import annotations

import enum
from collections.abc import Iterable
from dataclasses import dataclass
from itertools import zip_longest
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import can

DEFAULT_TIME_TOLERANCE_S = 1e-6
"""Times within this count as the same: a microsecond, the coarsest resolution of the formats."""


class TimeRule(enum.StrEnum):
    IGNORE = "ignore"
    RELATIVE = "relative"  # since each log's first frame
    ABSOLUTE = "absolute"  # UTC seconds, as every reader gives them


def frame_text(message: can.Message) -> str:
    """'0x190 [8] 01 02 03 04 05 06 07 08', '0x18FF0010 [2] ...', '0x123 remote [4]', 'error frame'."""
    if message.is_error_frame:
        return f"error frame 0x{message.arbitration_id:08X}"
    can_id = (
        f"0x{message.arbitration_id:08X}" if message.is_extended_id else f"0x{message.arbitration_id:03X}"
    )
    if message.is_remote_frame:
        return f"{can_id} remote [{message.dlc}]"
    data = bytes(message.data)
    return f"{can_id} [{len(data)}] {data.hex(' ').upper()}".rstrip()


def _difference(base: can.Message, cand: can.Message) -> str | None:
    """What differs between two frames, times aside; None when they are the same frame."""
    if (base.is_error_frame, base.is_remote_frame) != (cand.is_error_frame, cand.is_remote_frame):
        return "kind of frame"
    if (base.arbitration_id, base.is_extended_id) != (cand.arbitration_id, cand.is_extended_id):
        return "identifier"
    if base.is_remote_frame or base.is_error_frame:
        return None  # candump keeps no length of a remote frame: its identifier is the frame
    if bytes(base.data) != bytes(cand.data):
        return "length" if len(base.data) != len(cand.data) else "data"
    return None


@dataclass(frozen=True)
class LogDifference:
    number: int  # of the frame, from 1, among those compared
    base: can.Message | None  # None: BASE ended before it
    cand: can.Message | None
    what: str
    base_t: float | None  # as compared: since the log's first frame, or absolute
    cand_t: float | None


@dataclass(frozen=True)
class LogComparison:
    frames: int  # frames that agreed
    times: TimeRule
    tolerance_s: float
    difference: LogDifference | None

    @property
    def same(self) -> bool:
        return self.difference is None

    def summary(self) -> list[str]:
        """The verdict and, when the logs differ, the two frames."""
        if self.times is TimeRule.IGNORE:
            times = "times ignored"
        else:
            since = "since each log's first frame" if self.times is TimeRule.RELATIVE else "absolute"
            times = f"times {since} within {self.tolerance_s:g} s"
        difference = self.difference
        if difference is None:
            return [f"bus logs agree: {self.frames} frames ({times})"]
        if difference.base is None or difference.cand is None:
            short, other = ("BASE", "CAND") if difference.base is None else ("CAND", "BASE")
            ends = f"{short} ends after {self.frames} frames, {other} goes on"
            head = f"bus logs differ at frame {difference.number}: {ends}"
        else:
            head = f"bus logs differ at frame {difference.number}: {difference.what} ({times})"
        lines = [head]
        for name, message, t in (
            ("BASE", difference.base, difference.base_t),
            ("CAND", difference.cand, difference.cand_t),
        ):
            if message is not None:
                lines.append(f"  {name}  {t:.6f}  {frame_text(message)}")
        return lines


def compare_logs(
    base: Iterable[can.Message],
    cand: Iterable[can.Message],
    *,
    times: TimeRule = TimeRule.IGNORE,
    tolerance_s: float = DEFAULT_TIME_TOLERANCE_S,
    ignore_ids: frozenset[int] = frozenset(),
) -> LogComparison:
    """The first frame at which `cand` differs from `base` (frames on `ignore_ids` left out of
    both); the times shown are since each log's first frame unless `times` is ABSOLUTE."""

    def kept(messages: Iterable[can.Message]) -> Iterable[can.Message]:
        return (m for m in messages if m.is_error_frame or m.arbitration_id not in ignore_ids)

    base_start: float | None = None
    cand_start: float | None = None
    agreed = 0
    for number, (b, c) in enumerate(zip_longest(kept(base), kept(cand)), start=1):
        if b is not None and base_start is None:
            base_start = 0.0 if times is TimeRule.ABSOLUTE else b.timestamp
        if c is not None and cand_start is None:
            cand_start = 0.0 if times is TimeRule.ABSOLUTE else c.timestamp
        base_t = b.timestamp - base_start if b is not None and base_start is not None else None
        cand_t = c.timestamp - cand_start if c is not None and cand_start is not None else None
        what = None if b is None or c is None else _difference(b, c)
        if what is None and b is not None and c is not None and times is not TimeRule.IGNORE:
            assert base_t is not None and cand_t is not None
            if abs(base_t - cand_t) > tolerance_s:
                what = f"time, {cand_t - base_t:+.6f} s"
        if b is None or c is None or what is not None:
            return LogComparison(
                agreed, times, tolerance_s, LogDifference(number, b, c, what or "", base_t, cand_t)
            )
        agreed += 1
    return LogComparison(agreed, times, tolerance_s, None)


__all__ = [
    "DEFAULT_TIME_TOLERANCE_S",
    "LogComparison",
    "LogDifference",
    "TimeRule",
    "compare_logs",
    "frame_text",
]
