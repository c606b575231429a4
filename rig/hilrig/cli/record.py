"""`hilrig record FILE` and `hilrig replay FILE`: bus traffic to and from log files.

The format follows the extension (`hilrig.session.logformats`): `.log` (candump -L), `.asc` and
`.blf` (Vector), `.mf4` (ASAM MDF4, with asammdf), `.csv`, `.trc`, times in UTC and exact to the
format's resolution; `replay` also reads what else python-can reads (`.db`, gzipped
`.log.gz`...). `record` writes into a hidden
temporary file beside FILE and renames it to FILE only after the logger was stopped (flushed
and closed; a BLF file gets its header and object count only then), so FILE is always a whole
log: after Ctrl-C, SIGTERM, `--duration` or `--count` alike. A hard kill (SIGKILL) leaves FILE
untouched and the partial file behind.
"""

from __future__ import annotations

import argparse
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

from hilrig.cli.common import (
    DBC_HINT,
    LIVE_VIEWER_HELP,
    CanFilter,
    Command,
    UsageError,
    add_bus_options,
    add_table_option,
    dbc_path,
    describe_bus,
    existing_file,
    format_unit,
    format_value,
    live_sink,
    load_dbc,
    load_eds,
    load_table,
    node_id,
    open_bus,
    positive_float,
    positive_int,
    progress,
    value_names,
)
from hilrig.cli.files import ArgKind, kind, output_file, sniff_dbc, unreadable_reason
from hilrig.session.buslog import LOG_FORMATS, NodeDbc, master_side, partial_path, read_log, whole_file_logger

if TYPE_CHECKING:
    from hilrig.apps.log_trace import LiveBusTrace
    from hilrig.session.canbus import Bus, Listener, Message
    from hilrig.table import RigTable
    from hilrig.wire.node import ObjectDictionary

PROGRESS_EVERY_S = 1.0


log_path = output_file("log", suffixes=tuple(LOG_FORMATS))
"""record's FILE: the format follows the extension (.log is candump, .asc/.blf Vector, .mf4 ASAM)."""


class _CountingSink:
    """python-can listener: passes frames to `sink` and counts them; after `limit` frames it
    drops the rest and signals `done`, so `--count N` writes exactly N frames. With `filters`,
    only frames one of them keeps (the bus applies plain filters already; an inverted one,
    `ID~MASK`, only here)."""

    def __init__(self, sink: Listener, limit: int | None, filters: list[CanFilter] | None = None) -> None:
        self.sink = sink
        self.count = 0
        self.limit = limit
        self.filters = filters
        self.done = threading.Event()
        self._lock = threading.Lock()

    def __call__(self, message: Message) -> None:
        if self.filters and not any(f.keeps(message.arbitration_id) for f in self.filters):
            return
        with self._lock:
            if self.done.is_set():
                return
            self.sink.on_message_received(message)
            self.count += 1
            if self.limit is not None and self.count >= self.limit:
                self.done.set()


def nmt_target(args: argparse.Namespace) -> int | None:
    """The node --nmt-start starts (None without it). Worked out before the recording starts:
    loading the table takes seconds on a slow machine, and every frame meanwhile (heartbeats)
    would count towards --count before the NMT command is even sent."""
    if not args.nmt_start:
        return None
    return int(args.node_id if args.node_id is not None else load_table(args).board.node.default_node_id)


@contextmanager
def master_traffic(bus: Bus, args: argparse.Namespace, target: int | None) -> Iterator[None]:
    """Optionally act as the master of a board with no master: NMT start to `target`, SYNC
    producer."""
    if target is None and not args.sync_period_ms:
        yield
        return
    from boardproto.cia301 import NmtCommand
    from hilrig.engine.realtime import SyncProducer
    from hilrig.wire.master import BusMaster

    with BusMaster(bus) as master:  # only sends: the recorder's notifier reads
        if target is not None:
            master.nmt(NmtCommand.START, target)
        if args.sync_period_ms:
            with SyncProducer(master.sync, args.sync_period_ms / 1e3):
                yield
        else:
            yield


def configure_record(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", type=log_path, metavar="FILE", help=f"log file: {', '.join(LOG_FORMATS)}")
    parser.add_argument("--duration", type=positive_float, metavar="S", help="stop after S seconds")
    parser.add_argument("--count", type=positive_int, metavar="N", help="stop after N frames")
    parser.add_argument(
        "--nmt-start",
        action="store_true",
        help="send NMT start to --node-id first (a board with no master sends no PDOs)",
    )
    parser.add_argument(
        "--sync-period-ms",
        type=positive_float,
        metavar="P",
        help="send SYNC every P ms while recording (lockstep firmware sends TPDOs only on SYNC)",
    )
    parser.add_argument(
        "-n",
        "--node-id",
        type=node_id,
        default=None,
        help="node for --nmt-start (default: from the table, 0x10)",
    )
    parser.add_argument(
        "--viewer",
        action="append",
        type=live_sink,
        default=None,
        metavar="WHERE",
        help="also stream the recorded frames live to Rerun, PDO fields decoded with the DBC on the "
        "wall-clock timeline (repeatable): " + LIVE_VIEWER_HELP + "; a web viewer serves while recording",
    )
    parser.add_argument(
        "--dbc",
        type=existing_file("DBC", DBC_HINT, suffixes=(".dbc",), sniff=sniff_dbc),
        default=None,
        help="--viewer: the DBC (default: build/protocol/board.dbc)",
    )
    add_table_option(parser)
    add_bus_options(parser, filters=True)


def run_record(args: argparse.Namespace) -> int:
    from hilrig.session.canbus import Notified

    path: Path = args.file
    started = time.monotonic()
    deadline = started + args.duration if args.duration else None
    interactive = sys.stderr.isatty()
    if args.nmt_start or args.sync_period_ms:
        import hilrig.wire.master  # noqa: F401  (seconds in the VM: imported before frames are counted)
    live = None
    if args.viewer:
        from hilrig.apps.log_trace import LiveBusTrace

        table = load_table(args)
        node = args.node_id if args.node_id is not None else table.board.node.default_node_id
        dbc = NodeDbc(load_dbc(dbc_path(args)), table, node)
        progress("record: streaming live to " + ", ".join(map(str, args.viewer)) + " (importing rerun-sdk)")
        live = LiveBusTrace(args.viewer, dbc, table, node, name=path.stem)
        if live.tracer.web_url is not None:
            progress(f"record: web viewer at {live.tracer.web_url}")
    target = nmt_target(args)
    with open_bus(args, receive_own_messages=True) as bus, whole_file_logger(path) as logger:
        counter = _CountingSink(logger if live is None else _Both(logger, live), args.count, args.filters)
        notified = Notified(bus, [counter])
        try:
            limit = " (Ctrl-C to stop)" if not (args.count or args.duration) else ""
            kept = f", frames {' '.join(map(str, args.filters))}" if args.filters else ""
            progress(f"record: {describe_bus(args)}{kept} -> {path}{limit}")
            with master_traffic(bus, args, target):
                while not counter.done.is_set():
                    wait = PROGRESS_EVERY_S
                    if deadline is not None:
                        wait = min(wait, deadline - time.monotonic())
                        if wait <= 0:
                            break
                    counter.done.wait(wait)
                    line = f"record: {counter.count} frames, {time.monotonic() - started:.1f} s"
                    print(
                        f"\r{line}" if interactive else line,
                        end="" if interactive else "\n",
                        file=sys.stderr,
                        flush=True,
                    )
        finally:
            notified.stop()
            if interactive:
                print(file=sys.stderr)
            if live is not None:
                live.stop()
    progress(f"record: {counter.count} frames written to {path}")
    if live is not None:
        progress(f"record: {live.stats.cycles} cycles, {live.stats.decoded} PDOs streamed live")
    return 0


class _Both:
    """Two listeners as one: the log file and the live trace get the same frames."""

    def __init__(self, first: Listener, second: LiveBusTrace) -> None:
        self.first, self.second = first, second

    def on_message_received(self, message: Message) -> None:
        self.first.on_message_received(message)
        self.second.on_message_received(message)


# --- replay ----------------------------------------------------------------------------
def configure_replay(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "file",
        type=existing_log,
        metavar="FILE",
        help=f"log file: {', '.join(LOG_FORMATS)} or anything else python-can reads",
    )
    parser.add_argument(
        "--decode",
        action="store_true",
        help="print each frame with its fields decoded by the DBC instead of sending",
    )
    parser.add_argument(
        "--dbc",
        type=existing_file("DBC", DBC_HINT, suffixes=(".dbc",), sniff=sniff_dbc),
        default=None,
        help="--decode and --trace: the DBC (default: the table's: build/protocol/board.dbc in a checkout)",
    )
    parser.add_argument(
        "--field",
        action="append",
        metavar="NAME",
        help="--decode: only frames carrying this field, only it shown (repeatable)",
    )
    parser.add_argument(
        "-n",
        "--node-id",
        type=node_id,
        default=None,
        help="node id the log's PDOs belong to, for --decode and --as-master (default: the table's, 0x10)",
    )
    parser.add_argument(
        "--trace",
        type=rrd_path,
        metavar="OUT.rrd",
        help="instead of sending: every PDO field decoded with the DBC into a Rerun trace, cycle by "
        "cycle (grouped by SYNC), with EMCY, SDO aborts and NMT changes; open it with "
        "`hilrig view OUT.rrd`",
    )
    parser.add_argument(
        "--no-timing", action="store_true", help="send as fast as possible instead of at the recorded pace"
    )
    parser.add_argument(
        "--as-master",
        action="store_true",
        help="leave out what the node (--node-id) sent: its TPDOs, SDO answers, heartbeat, EMCY; the "
        "log's master side (NMT, SYNC, RPDOs, SDO requests, injected frames) then drives a fresh node "
        "through the same run",
    )
    add_table_option(parser)
    add_bus_options(parser)


@kind(ArgKind("input file", suffixes=tuple(LOG_FORMATS)))
def existing_log(text: str) -> Path:
    """replay's FILE: a file that can be read; its format (the extension: LOG_FORMATS and what
    else python-can reads) is judged by `read_log` before the bus opens, which says what the
    content looks like."""
    path = Path(text)
    reason = unreadable_reason(path)
    if reason is not None:
        from hilrig.session.buslog import readable_formats  # imports python-can: only on this error

        raise argparse.ArgumentTypeError(
            f"log {text} {reason}; record one with `hilrig record FILE` (replay reads {readable_formats()})"
        )
    return path


rrd_path = output_file("trace", suffixes=(".rrd",))


def run_replay(args: argparse.Namespace) -> int:
    if args.decode and args.trace:
        raise UsageError("--decode prints, --trace writes a Rerun trace: choose one")
    if args.decode:
        return _decode(args)
    if args.trace:
        return _trace(args)
    from hilrig.session.canbus import paced

    sent = 0
    started = time.monotonic()
    next_report = started + PROGRESS_EVERY_S
    frames: Iterator[Message]
    with read_log(args.file) as logged, open_bus(args) as bus:
        frames = paced(logged, timestamps=not args.no_timing)
        if args.as_master:
            table = load_table(args)
            node = args.node_id if args.node_id is not None else table.board.node.default_node_id
            frames = master_side(frames, table, node)
            progress(f"replay: {args.file} -> {describe_bus(args)}, without node 0x{node:02X}'s own frames")
        else:
            progress(f"replay: {args.file} -> {describe_bus(args)}")
        for message in frames:
            bus.send(message, timeout=1.0)
            sent += 1
            if time.monotonic() >= next_report:
                progress(f"replay: {sent} frames, {time.monotonic() - started:.1f} s")
                next_report += PROGRESS_EVERY_S
    progress(f"replay: {sent} frames sent")
    return 0


def _trace(args: argparse.Namespace) -> int:
    from hilrig.apps.log_trace import trace_log
    from hilrig.observe.sinks import TraceSink
    from hilrig.observe.tracer import Tracer

    table = load_table(args)
    database = load_dbc(dbc_path(args))
    node = args.node_id if args.node_id is not None else table.board.node.default_node_id
    partial = partial_path(args.trace)
    with read_log(args.file) as logged:  # a format python-can does not read: said before rerun loads
        progress(f"replay: {args.file} -> {args.trace} (importing rerun-sdk)")
        tracer = Tracer(TraceSink.rrd(partial), table, clock="wall", recording_name=args.file.stem)
        try:
            stats = trace_log(
                logged,
                NodeDbc(database, table, node),
                table,
                node,
                tracer,
                progress=lambda n: progress(f"replay: {n} frames traced"),
            )
        except BaseException:
            tracer.close()
            partial.unlink(missing_ok=True)  # a log that breaks off leaves no half trace behind
            raise
        tracer.close()
    if stats.frames == 0:
        partial.unlink(missing_ok=True)
        raise UsageError(f"{args.file} holds no frames")
    partial.replace(args.trace)  # whole, or not there at all
    progress(
        f"replay: {stats.frames} frames, {stats.cycles} cycles, {stats.decoded} PDOs decoded "
        f"({stats.undecodable} did not fit their DBC message), {stats.events} events -> {args.trace}"
    )
    print(f"hilrig view {args.trace}   # add --web on a machine without a display")
    return 0


def describe_frame(cob_id: int, data: bytes, node: int) -> str:
    """CiA 301 services that are not in the DBC, in words."""
    from boardproto.cia301 import (
        HEARTBEAT_STATE_MASK,
        NMT_COB_ID,
        SYNC_COB_ID,
        FunctionCode,
        function_of,
    )
    from hilrig.cli.scan import state_name
    from hilrig.wire.node import EmcyRecord

    function, sender = function_of(cob_id)
    if cob_id == NMT_COB_ID and len(data) >= 2:
        return f"NMT command 0x{data[0]:02X} to {'all' if data[1] == 0 else f'node 0x{data[1]:02X}'}"
    if cob_id == SYNC_COB_ID:
        return f"SYNC {data[0]}" if data else "SYNC"
    if function == FunctionCode.SYNC_EMCY:
        return f"{EmcyRecord.from_frame(bytes(data)).summary} from node 0x{sender:02X}"
    if function == FunctionCode.HEARTBEAT and len(data) == 1:
        return f"heartbeat node 0x{sender:02X} {state_name(data[0] & HEARTBEAT_STATE_MASK)}"
    return ""


def _decode(args: argparse.Namespace) -> int:
    table = load_table(args)
    if args.field:
        from hilrig.cli.common import check_names

        check_names(table, args.field)
    database = load_dbc(dbc_path(args))
    node = args.node_id if args.node_id is not None else table.board.node.default_node_id
    decoder = FrameDecoder(
        NodeDbc(database, table, node), table, node, set(args.field or ()), od=sdo_dictionary(args, node)
    )
    first: float | None = None
    frames = 0
    with read_log(args.file) as logged:
        try:
            for message in logged:
                frames += 1
                first = message.timestamp if first is None else first
                text = decoder.describe(message)
                if text is not None:
                    sys.stdout.write(
                        f"{message.timestamp - first:12.6f}  0x{message.arbitration_id:03X}  {text}\n"
                    )
        except BrokenPipeError:  # `| head` closed the pipe: that is fine
            sys.stderr.close()
            return 0
    if frames == 0:
        raise UsageError(f"{args.file} holds no frames")
    return 0


def sdo_dictionary(args: argparse.Namespace, node: int) -> ObjectDictionary | None:
    """The table's EDS, when it is built, for the names and types of the objects an SDO transfer
    names that the table does not (0x1000..0x1FFF); without it they show by index."""
    from hilrig import resources

    path = resources.eds_for(args.table)
    return load_eds(path, node) if path.is_file() else None


class FrameDecoder:
    """One frame in words: its fields decoded by the DBC, an SDO transfer's step with the
    table's names (`hilrig.wire.sdo`: each node's transfers followed frame by frame), or the
    CiA 301 service (replay --decode, hilrig monitor). Feed it every frame, in order."""

    def __init__(
        self,
        dbc: NodeDbc,
        table: RigTable,
        node: int,
        wanted: set[str],
        od: ObjectDictionary | None = None,
    ) -> None:
        from hilrig.wire.sdo import ObjectWords, SdoTracker

        self.dbc = dbc
        self.node = node
        self.wanted = wanted  # --field: only frames with these, only these shown
        self.units = {e.name: format_unit(e.unit) for e in table.board.entries}
        self.named = value_names(table)
        self.sdo = SdoTracker()
        self.words = ObjectWords(table, self._value, od)

    def describe(self, message: Message) -> str | None:
        """The text of the frame; None when --field leaves it out."""
        data = bytes(message.data)
        dbc_message = self.dbc.message(message.arbitration_id)
        if dbc_message is None or message.is_extended_id:
            step = None if message.is_extended_id else self.sdo.feed(message.arbitration_id, data)
            if self.wanted:
                return None
            if step is not None:
                return step.describe(self.words)
            return describe_frame(message.arbitration_id, data, self.node) or data.hex(" ")
        try:
            values = dbc_message.decode(data, decode_choices=False)
        except Exception as error:  # a frame that does not fit its DBC message
            return f"{dbc_message.name} (undecodable: {error})"
        shown = {k: v for k, v in values.items() if not self.wanted or k in self.wanted}
        if self.wanted and not shown:
            return None
        return f"{dbc_message.name}  " + "  ".join(self._value(k, v) for k, v in shown.items())

    def _value(self, name: str, value: float) -> str:
        unit = self.units.get(name)
        return f"{name}={format_value(value, self.named.get(name))}{' ' + unit if unit else ''}"


COMMANDS = (
    Command(
        name="record",
        help="record bus traffic to a .log (candump), .asc, .blf or .mf4 file; Ctrl-C leaves a whole file",
        description=__doc__.split("\n", 1)[1].strip() + "\n\n"
        "  hilrig record out/bus.log                         # until Ctrl-C\n"
        "  hilrig record bus.blf --duration 10 --channel can0\n"
        "  hilrig record bus.mf4 --duration 10                # for CANape / asammdf\n"
        "  hilrig record bus.log --nmt-start --sync-period-ms 10 --count 500  # no master",
        configure=configure_record,
        run=run_record,
    ),
    Command(
        name="replay",
        help="send a recorded log into the bus, or --decode it with the DBC",
        description="Send the frames of a log into the bus at their recorded pace (python-can's\n"
        "LogReader + MessageSync), or with --decode print every frame with its fields\n"
        "decoded by the DBC (no bus needed).\n\n"
        "  hilrig replay out/demo/bus.log --decode | less\n"
        "  hilrig replay out/demo/bus.log --decode --field motor_velocity\n"
        "  hilrig replay bus.log --channel vcan1\n"
        "  hilrig replay bench.log --trace bench.rrd     # a Rerun trace of a recorded board\n"
        "  hilrig replay run1.log --as-master             # drive a fresh firmware through run 1",
        configure=configure_replay,
        run=run_replay,
    ),
)
