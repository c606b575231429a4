"""Bus logs: written whole through python-can's loggers, and the master side of a log.

`whole_file_logger` is the one way the project writes a log (`hilrig record`, `hilrig convert`,
`hilrig sim`, every scenario's bus log): python-can's writer for the extension
(`hilrig.session.logformats`: .log candump, .asc and .blf Vector, .mf4 ASAM MDF4, .csv, .trc)
writing to a hidden partial file that is renamed to the real name only once
the logger was stopped (flushed and closed; a BLF file gets its header and object count only
then). So the named file is always a whole log, also after Ctrl-C or SIGTERM; a hard kill
(SIGKILL) leaves it untouched and the partial file behind.

`read_log` is the one way the command line reads a log: python-can's reader for the extension
(`logformats.open_reader`; also gzipped), with every problem of the file said in one line that names it.

`RecorderProcess` runs that logger in a process of its own, forked from a warm server: every
frame becomes a python-can Message there, and in the rig's own process those would compete with
the lockstep loop for the interpreter lock.
"""

from __future__ import annotations

import contextlib
import gzip
import os
import re
import signal
import threading
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from boardproto.cia301 import TPDO_FUNCTIONS, cob_id, emcy_cob_id, heartbeat_cob_id, sdo_response_cob_id
from hilrig.errors import LogFileError, LogFormatError, one_line
from hilrig.session.logformats import DEFAULT_BLF_CLOCK, LOG_FORMATS, open_reader, open_writer
from hilrig.table import RigTable

if TYPE_CHECKING:
    import can
    import cantools.database


_CANDUMP_LOG_LINE = re.compile(r"\(\d+(\.\d+)?\)\s+\S+\s+[0-9A-Fa-f]+#")  # (1700000000.000000) can0 123#1122
_CANDUMP_SCREEN_LINE = re.compile(r"(\(\S+\)\s+)?\S+\s+[0-9A-Fa-f]+\s+\[\d+\]")  # can0  123   [2]  11 22


def partial_path(path: Path) -> Path:
    """Hidden temporary name beside `path`, with the same extension (it picks the format)."""
    return path.with_name(f".{path.stem}.partial{path.suffix}")


@contextmanager
def whole_file_logger(path: Path, *, blf_clock: str = DEFAULT_BLF_CLOCK) -> Iterator[can.Listener]:
    """A python-can writer whose file appears at `path` only whole (see the module)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = partial_path(path)
    try:
        logger = open_writer(partial, blf_clock=blf_clock)
    except NotImplementedError as error:  # .mf4 without asammdf
        raise LogFormatError(f"{path}: {one_line(error)}") from error
    try:
        yield logger
    finally:
        logger.stop()  # flush and close: the file is complete from here on
        os.replace(partial, path)


def reader_suffixes() -> frozenset[str]:
    """The extensions python-can has a reader for ('.log', '.asc', '.db'...)."""
    from can.io.player import MESSAGE_READERS

    return frozenset(MESSAGE_READERS)


def readable_formats() -> str:
    """The extensions python-can's LogReader reads, from python-can itself."""
    from can.io.player import MESSAGE_READERS

    names = [_kind(suffix) for suffix in sorted(MESSAGE_READERS)]
    return ", ".join(names) + ", each also gzipped (.log.gz)"


def _format_of(path: Path) -> str:
    """The extension that picks the reader, as python-can sees it: 'bus.log.gz' -> '.log'."""
    suffixes = [suffix.lower() for suffix in path.suffixes]
    if suffixes[-1:] == [".gz"]:
        return suffixes[0] if len(suffixes) == 2 else ".gz"
    return suffixes[-1] if suffixes else ""


def _first_line(path: Path) -> str:
    try:
        with gzip.open(path, "rb") if path.suffix.lower() == ".gz" else path.open("rb") as file:
            return file.readline(200).decode("ascii", "replace").strip()
    except (OSError, EOFError):
        return ""


def _content_hint(path: Path, suffix: str) -> str:
    """What a candump file in the wrong form or under the wrong name needs."""
    line = _first_line(path)
    if suffix == ".log" and _CANDUMP_SCREEN_LINE.match(line):
        return (
            "; this is candump's screen output: python-can reads its log form, `candump -L` "
            "(or `hilrig record`), lines like '(1700000000.000000) can0 123#1122'"
        )
    if suffix != ".log" and _CANDUMP_LOG_LINE.match(line):
        return "; its first line is candump -L: name the file *.log"
    return ""


def _kind(suffix: str) -> str:
    return f"{suffix} (candump -L)" if suffix == ".log" else suffix


@contextmanager
def read_log(path: Path, *, blf_clock: str = DEFAULT_BLF_CLOCK) -> Iterator[Iterator[can.Message]]:
    """The frames of the log at `path`, read by python-can (format by extension, `open_reader`).

    A format python-can does not read (or not without a package this machine lacks) raises
    LogFormatError; content it cannot parse, at the start or part-way, LogFileError. Both name
    the file; the first lists the formats read."""
    from can.io.player import MESSAGE_READERS

    suffix = _format_of(path)
    if suffix not in MESSAGE_READERS:
        shown = f"{suffix} files" if suffix else "files without an extension"
        raise LogFormatError(
            f"{path}: python-can reads no {shown} (the format follows the extension); it reads "
            f"{readable_formats()}{_content_hint(path, suffix)}"
        )
    try:
        reader = open_reader(path, blf_clock=blf_clock)
    except (NotImplementedError, ImportError) as error:  # .mf4 without asammdf
        raise LogFormatError(f"{path}: {one_line(error)}") from error
    except Exception as error:  # the reader's parse errors have no common base
        raise LogFileError(
            f"{path}: python-can cannot read this {_kind(suffix)} file ({one_line(error)})"
            f"{_content_hint(path, suffix)}"
        ) from error
    try:
        yield _checked_frames(path, suffix, reader)
    finally:
        reader.stop()


def _checked_frames(path: Path, suffix: str, frames: Iterable[can.Message]) -> Iterator[can.Message]:
    count = 0
    iterator = iter(frames)
    while True:
        try:
            message = next(iterator)
        except StopIteration:
            return
        except Exception as error:  # only python-can's parser runs here: the file is at fault
            where = f"after frame {count}" if count else "from its start"
            raise LogFileError(
                f"{path}: python-can cannot read this {_kind(suffix)} file {where} ({one_line(error)})"
                f"{_content_hint(path, suffix)}"
            ) from error
        count += 1
        yield message


class BusRecorder:
    """Everything on a bus into a whole log, from a socket of its own (so it sees every
    sender's frames alike), until `close()`, which also logs what its socket still holds (a
    receive thread behind a fast sender, as in the emulated VM, must not lose the run's end).
    The recorder owns `bus` and shuts it down."""

    def __init__(self, bus: can.BusABC, path: Path) -> None:
        import can

        self.path = path
        self._bus = bus
        self._stack = contextlib.ExitStack()
        self._stack.callback(bus.shutdown)
        logger = self._stack.enter_context(whole_file_logger(path))
        self._stack.callback(_log_queued, bus, logger)  # runs second, with the thread stopped
        # The logger's method, not the logger: Notifier.stop() would stop (close) a Listener
        # before the queue is logged; whole_file_logger closes it last.
        self._notifier = can.Notifier(bus, [logger.on_message_received], timeout=0.05)
        self._stack.callback(self._notifier.stop)  # runs first: no frame after the logger stops

    def close(self) -> None:
        self._stack.close()


def _log_queued(bus: can.BusABC, logger: can.Listener) -> None:
    """Log every frame `bus` has queued (until a receive finds none)."""
    while (message := bus.recv(timeout=0.0)) is not None:
        logger(message)


class _Launcher(Protocol):
    channel: str
    namespace_file: Path | None
    """The network namespace the channel lives in (None: this process's own)."""


class RecorderProcess:
    """Everything on `launcher`'s bus into a whole log at `path`, recorded by a process of its
    own, ready once the constructor returns. The process is forked from the warm server
    (`hilrig.session.warm`, which has python-can imported) and moves into the bus's network
    namespace itself. `close()` stops it (SIGTERM: the log is renamed whole) and returns the
    number of frames it wrote; if the rig's process dies first (even by SIGKILL), the recorder
    ends by itself, its log whole, instead of recording an abandoned bus forever."""

    READY_TIMEOUT_S = 120.0
    """Hang guard for the start (the server's own start imports python-can: seconds in the
    emulated VM)."""
    STOP_TIMEOUT_S = 60.0

    def __init__(self, launcher: _Launcher, path: Path) -> None:
        from hilrig.session import warm

        self.path = path
        self.frames: int | None = None
        path.parent.mkdir(parents=True, exist_ok=True)
        context = warm.context()
        self._said, told = context.Pipe(duplex=False)
        self.process = context.Process(
            target=_record_process,
            args=(launcher.namespace_file, launcher.channel, path, told),
            name=f"bus recorder {path}",
            daemon=True,  # also stopped (SIGTERM, log whole) if the rig's process ends first
        )
        self.process.start()
        told.close()
        said = self._said.recv() if self._said.poll(self.READY_TIMEOUT_S) else None
        if said != "ready":
            self.process.kill()
            self.process.join()
            raise RuntimeError(
                f"bus recorder for {path} did not start (exit {self.process.exitcode}, said {said!r})"
            )

    def close(self) -> int | None:
        """Stop the recorder; the frames it wrote (None if it did not say)."""
        if self.process.is_alive():
            self.process.terminate()  # SIGTERM: the recorder logs what is queued, then renames
        try:
            if self._said.poll(self.STOP_TIMEOUT_S):
                said = self._said.recv()
                if isinstance(said, int):
                    self.frames = said
        except EOFError:
            pass  # it ended without saying (killed): no count
        self.process.join(self.STOP_TIMEOUT_S)
        self._said.close()
        return self.frames


RECORD_BATCH = 256
"""Frames the recorder takes per call at most (`RawCanLink.receive_stamped`)."""
GATHER_S = 0.01
"""How long the recorder lets frames gather once one is queued: one wake-up for a burst (a
lockstep cycle's frames come together) instead of one per frame. Each frame carries the kernel's
receive time, so the log is the same; the receive queue (`RECEIVE_QUEUE_BYTES`) holds some
20 000 frames, far more than any bus here sends in that time."""


def _record_process(namespace_file: Path | None, channel: str, out: Path, tell: Any) -> None:
    """The recorder process: every frame of a SocketCAN channel into python-can's logger until
    SIGTERM/SIGINT. Frames are read from a raw socket with kernel timestamps, a batch per system
    call (`hilrig.wire.transport`): inside the emulated VM the recorder's Python work per frame
    competes with the lockstep rig for the same two vCPUs. Says "ready" on `tell`, then the frame
    count."""
    import multiprocessing
    import time

    import can

    from hilrig.session.warm import enter_namespace
    from hilrig.wire.transport import RawCanLink, open_raw_socket

    stop = threading.Event()
    for number in (signal.SIGTERM, signal.SIGINT):
        signal.signal(number, lambda *_: stop.set())
    enter_namespace(namespace_file)
    parent = multiprocessing.parent_process()
    link = RawCanLink(open_raw_socket(channel, None))
    link.enable_timestamps()
    message = can.Message
    frames = 0
    with contextlib.closing(link), whole_file_logger(out) as logger:
        tell.send("ready")
        while True:
            batch = link.receive_stamped(RECORD_BATCH)
            for can_id, data, stamp in batch:
                logger(
                    message(
                        timestamp=stamp,
                        arbitration_id=can_id & (_EFF_MASK if can_id & _EFF_FLAG else _SFF_MASK),
                        is_extended_id=bool(can_id & _EFF_FLAG),
                        is_remote_frame=bool(can_id & _RTR_FLAG),
                        is_error_frame=bool(can_id & _ERR_FLAG),
                        dlc=len(data),
                        data=data,
                        channel=channel,
                        check=False,
                    )
                )
            frames += len(batch)
            if len(batch) == RECORD_BATCH:
                continue  # more queued
            # Stopped, or the rig died (SIGKILL): end whole once nothing is queued any more.
            if stop.is_set() or (parent is not None and not parent.is_alive()):
                if not batch:
                    break
                continue
            if link.wait_readable(0.05):
                time.sleep(GATHER_S)
    tell.send(frames)


_EFF_FLAG, _RTR_FLAG, _ERR_FLAG = 0x8000_0000, 0x4000_0000, 0x2000_0000
_SFF_MASK, _EFF_MASK = 0x7FF, 0x1FFF_FFFF


def node_cob_ids(table: RigTable, node_id: int) -> frozenset[int]:
    """COB-IDs node `node_id` itself sends on (CiA 301 predefined connection set and the
    table's TPDOs): EMCY, TPDOs, SDO answers, heartbeat and boot-up."""
    tpdos = {pdo.cob_id(node_id) for pdo in table.board.tpdos}
    fixed = {emcy_cob_id(node_id), sdo_response_cob_id(node_id), heartbeat_cob_id(node_id)}
    fixed |= {cob_id(function, node_id) for function in TPDO_FUNCTIONS}
    return frozenset(tpdos | fixed)


def master_side(messages: Iterator[can.Message], table: RigTable, node_id: int) -> Iterator[can.Message]:
    """The frames of a log that node `node_id` did not send itself: what the master (and any
    other sender, e.g. an injected flood) put on the bus. Replayed into a fresh node, they drive
    it through the same run."""
    own = node_cob_ids(table, node_id)
    for message in messages:
        if message.is_extended_id or message.arbitration_id not in own:
            yield message


class NodeDbc:
    """The generated DBC read for node `node_id`: the DBC holds the default node's COB-IDs,
    a board at another node id sends the same messages shifted by the difference."""

    def __init__(self, database: cantools.database.can.Database, table: RigTable, node_id: int) -> None:
        self.database = database
        self._offset = node_id - table.board.node.default_node_id

    def message(self, cob_id: int) -> cantools.database.can.Message | None:
        """The DBC message a frame on `cob_id` carries, or None (not a PDO of this node)."""
        try:
            return self.database.get_message_by_frame_id(cob_id - self._offset)
        except KeyError:
            return None


__all__ = [
    "LOG_FORMATS",
    "BusRecorder",
    "NodeDbc",
    "RecorderProcess",
    "master_side",
    "node_cob_ids",
    "partial_path",
    "whole_file_logger",
]
