"""Bus log formats: the one place that opens python-can's writer or reader for a file, with the
timestamp rules each format needs to keep a frame's time exact (UTC seconds since the epoch, as
every python-can Message carries it) through a write and a read.

- `.log` (candump -L): absolute times, microseconds. Nothing to fix.
- `.asc` (Vector ASCII): times relative to the "Begin Triggerblock" line, which has milliseconds
  only and is the wall clock of this machine's time zone, as CANoe writes it. python-can's writer
  puts the first frame's exact time there (its sub-millisecond part is lost on reading), and its
  reader gives times relative to the file unless asked: here the block starts on the
  millisecond at or before the first frame and the reader always gives absolute times.
- `.blf` (Vector binary): frame times in nanoseconds relative to a start time in the header, a
  SYSTEMTIME with milliseconds and no time zone. CANoe and CANalyzer write and read it as local
  time; python-can (since 4.5) as UTC, so a file crossing between them shifts by the machine's UTC
  offset (python-can issues #1992, #2010). Here the header is local time by default, as Vector's
  tools have it (`BLF_CLOCKS`: "utc" reads or writes python-can's way).
- `.mf4` (ASAM MDF 4, through asammdf): frame times relative to the header's start time
  (nanoseconds since the epoch, UTC). python-can's writer takes the moment the file was opened as
  the start, so a converted old log has negative times in CANape; here the start is the first
  frame's time.
- `.csv`, `.trc`: python-can's own writers, as they are.
"""

from __future__ import annotations

import datetime
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import can
    from can.io.generic import MessageReader

LOG_FORMATS = (".log", ".asc", ".blf", ".mf4", ".csv", ".trc")
"""The formats the project writes, by extension (python-can reads more: `buslog.readable_formats`)."""

FORMAT_NAMES = {
    ".log": "candump -L",
    ".asc": "Vector ASC",
    ".blf": "Vector BLF",
    ".mf4": "ASAM MDF4",
    ".csv": "python-can CSV",
    ".trc": "PEAK TRC",
}

BLF_CLOCKS = ("local", "utc")
"""How a BLF header's start time is read and written: the machine's local time (Vector's tools)
or UTC (python-can's BLFWriter and BLFReader)."""
DEFAULT_BLF_CLOCK = "local"

MF4_HINT = "install asammdf (pip install 'hilrig[mf4]'; `make build` has it in .venv)"


def _local_offset_s(utc_timestamp: float) -> float:
    """The local time zone's UTC offset at that instant, in seconds (daylight saving included)."""
    offset = datetime.datetime.fromtimestamp(utc_timestamp).astimezone().utcoffset()
    return offset.total_seconds() if offset is not None else 0.0


def _wall_to_utc(wall: float) -> float:
    """A local wall-clock time written as if it were UTC (what python-can's BLFReader makes of a
    local SYSTEMTIME) back to the true UTC timestamp."""
    naive = datetime.datetime.fromtimestamp(wall, tz=datetime.UTC).replace(tzinfo=None)
    return naive.timestamp()  # a naive datetime is local time


def open_writer(path: Path, *, blf_clock: str = DEFAULT_BLF_CLOCK) -> can.Listener:
    """A python-can writer for `path`, the format by its extension (`LOG_FORMATS`)."""
    import can

    suffix = path.suffix.lower()
    if suffix == ".asc":
        return _asc_writer_class()(str(path))
    if suffix == ".blf":
        return _blf_writer_class()(str(path), clock=_checked_clock(blf_clock))
    if suffix == ".mf4":
        _need_asammdf()
        return _mf4_writer_class()(str(path))
    return can.Logger(str(path))


def open_reader(path: Path, *, blf_clock: str = DEFAULT_BLF_CLOCK) -> MessageReader:
    """A python-can reader for `path` (its `stop()` closes it), the format by its extension;
    what python-can reads besides `LOG_FORMATS` (gzipped logs, .db...) through `can.LogReader`."""
    import can

    suffix = path.suffix.lower()
    if suffix == ".asc":
        return can.ASCReader(str(path), relative_timestamp=False)
    if suffix == ".blf":
        reader = can.BLFReader(str(path))
        if _checked_clock(blf_clock) == "local" and reader.start_timestamp:
            reader.start_timestamp = _wall_to_utc(reader.start_timestamp)
            reader.stop_timestamp = _wall_to_utc(reader.stop_timestamp) if reader.stop_timestamp else 0
        return reader
    if suffix == ".mf4":
        _need_asammdf()
    return can.LogReader(str(path))


def _checked_clock(clock: str) -> str:
    if clock not in BLF_CLOCKS:
        raise ValueError(f"BLF clock {clock!r}: choose one of {', '.join(BLF_CLOCKS)}")
    return clock


def _need_asammdf() -> None:
    from hilrig import mf4_deferred

    try:
        mf4_deferred.enable()
    except ImportError:
        raise NotImplementedError(f".mf4 files need asammdf: {MF4_HINT}") from None


def _floor(timestamp: float, resolution: float) -> float:
    return math.floor(timestamp / resolution) * resolution


def _asc_writer_class() -> type[can.ASCWriter]:
    import can

    class ExactASCWriter(can.ASCWriter):
        """python-can's ASCWriter with the trigger block starting on a whole millisecond (the
        line's resolution), so the frames' relative times carry their exact microseconds."""

        def log_event(self, message: str, timestamp: float | None = None) -> None:
            if message and not self.header_written:
                start = _floor(timestamp or 0.0, 1e-3)
                self.started = self.last_timestamp = start
                when = self._format_header_datetime(datetime.datetime.fromtimestamp(start))
                self.file.write(f"Begin Triggerblock {when}\n")
                self.header_written = True
                super().log_event("Start of measurement", start)
            super().log_event(message, timestamp)

    return ExactASCWriter


def _blf_writer_class() -> type[can.BLFWriter]:
    import can

    class ClockedBLFWriter(can.BLFWriter):
        """python-can's BLFWriter whose header times are local time (Vector's tools) or UTC."""

        def __init__(self, file: str, clock: str, **kwargs: Any) -> None:
            self._clock = clock
            super().__init__(file, **kwargs)

        def _write_header(self, filesize: int) -> None:
            start, stop = self.start_timestamp, self.stop_timestamp
            if self._clock == "local":  # a SYSTEMTIME of the local wall clock
                self.start_timestamp = None if start is None else start + _local_offset_s(start)
                self.stop_timestamp = None if stop is None else stop + _local_offset_s(stop)
            try:
                super()._write_header(filesize)
            finally:
                self.start_timestamp, self.stop_timestamp = start, stop

    return ClockedBLFWriter


def _mf4_writer_class() -> type[can.MF4Writer]:
    import can

    class FirstFrameMF4Writer(can.MF4Writer):
        """python-can's MF4Writer with the measurement starting at the first frame (to the
        header's microsecond) instead of when the file was opened."""

        _started = False

        def on_message_received(self, msg: can.Message) -> None:
            if not self._started and msg.timestamp is not None:
                start = _floor(msg.timestamp, 1e-6)
                self._mdf.header.start_time = datetime.datetime.fromtimestamp(start, tz=datetime.UTC)
                self._start_time = self.last_timestamp = self._mdf.header.start_time.timestamp()
            self._started = True
            super().on_message_received(msg)

    return FirstFrameMF4Writer


__all__ = [
    "BLF_CLOCKS",
    "DEFAULT_BLF_CLOCK",
    "FORMAT_NAMES",
    "LOG_FORMATS",
    "open_reader",
    "open_writer",
]
