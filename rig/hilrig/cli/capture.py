"""`hilrig capture FIELD...`: the board's field recorder: every cycle on the board, uploaded after.

Configures the recorder over SDO (channels by field name, samples, divider, trigger), arms it,
shows its progress until the recording is done (Ctrl-C disarms it and exits), uploads it by SDO
block transfer and writes a CSV (cycle, time, one column per field with its unit) and, with
--rrd, a Rerun trace laid out like the rig's.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path

from boardproto import UnknownNameError
from boardproto.table import BitSet
from hilrig.apps.capture import (
    CaptureError,
    CaptureSettings,
    Progress,
    RecorderClient,
    check_settings,
    recorder_of,
    write_csv,
    write_rrd,
)
from hilrig.cli.common import (
    Command,
    UsageError,
    add_node_options,
    board_node,
    check_names,
    field_name,
    load_table,
    open_bus,
    positive_float,
    positive_int,
    progress,
    silent_hint,
)
from hilrig.cli.files import output_file
from hilrig.errors import FieldNameError, RigError, SdoTimeoutError
from hilrig.session.run import RunDescription
from hilrig.table import RigTable


def percent(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole percentage 0..100, got {text!r}") from None
    if not 0 <= value <= 100:
        raise argparse.ArgumentTypeError(f"expected a whole percentage 0..100, got {text}")
    return value


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "names", type=field_name, nargs="+", metavar="FIELD", help="board fields to record, in column order"
    )
    parser.add_argument(
        "--samples",
        type=positive_int,
        default=None,
        metavar="N",
        help="samples to record (default: as many as the recorder holds for these fields)",
    )
    parser.add_argument(
        "--divider", type=positive_int, default=1, metavar="N", help="one sample every N control cycles"
    )
    parser.add_argument(
        "--trigger",
        default="immediate",
        metavar="SOURCE",
        help="immediate (default: from the first cycle), level (--trigger-field crosses --level) or "
        "flag (a bit of --bits in --trigger-field gets set/cleared)",
    )
    parser.add_argument("--trigger-field", metavar="FIELD", help="the field a level or flag trigger watches")
    parser.add_argument("--level", type=float, default=0.0, help="level trigger: the level crossed")
    parser.add_argument(
        "--edge", default="rising", help="rising (default), falling or either: which crossing fires"
    )
    parser.add_argument(
        "--bits",
        metavar="BITS",
        help="flag trigger: bit names of the field's bitset ('command_watchdog|over_temperature') or a mask",
    )
    parser.add_argument(
        "--pre",
        type=percent,
        default=0,
        metavar="PERCENT",
        help="share of the samples kept from before the trigger (default 0)",
    )
    parser.add_argument(
        "-o",
        "--csv",
        type=output_file("CSV", suffixes=(".csv",)),
        default=Path("capture.csv"),
        help="the CSV to write (default: capture.csv)",
    )
    parser.add_argument(
        "--rrd",
        type=output_file("trace", suffixes=(".rrd",)),
        help="also write the recording as a Rerun .rrd",
    )
    RunDescription.add_arguments(parser, "period_us")  # the board's period: the time column's
    parser.add_argument(
        "--timeout",
        type=positive_float,
        metavar="S",
        help="give up (disarming the recorder) when not done after S seconds (default: wait)",
    )
    parser.add_argument(
        "--sync-period-ms",
        type=positive_float,
        metavar="P",
        help="send SYNC every P ms: for a lockstep board with no master (one control cycle per SYNC)",
    )
    parser.add_argument(
        "--nmt-start",
        action="store_true",
        help="send NMT start first (a node with no master stays pre-operational: no SYNC is served)",
    )
    add_node_options(parser, writes=True)


def parse_bits(text: str | None, bitset: BitSet | None, field: str | None) -> int:
    """'command_watchdog|over_temperature' (names of the field's bitset) or a number."""
    if text is None:
        return 0
    if text[:1].isdigit():
        try:
            return int(text, 0)
        except ValueError:
            raise UsageError(f"--bits: expected bit names or a whole number, got {text!r}") from None
    if bitset is None:
        raise UsageError(f"--bits: {field} has no named bits in the table; give a number")
    try:
        return sum({bitset.bit(name.strip()).mask for name in text.split("|")})
    except UnknownNameError as error:
        raise UsageError(f"--bits: {error}") from None


def settings_from(args: argparse.Namespace, table: RigTable) -> CaptureSettings:
    """The recording the command line asks for; UsageError for what the table refuses."""
    fields = check_names(table, args.names)
    names = tuple(e.name for e in fields)
    if args.trigger_field is not None:
        check_names(table, [args.trigger_field])
    recorder = recorder_of(table)
    samples = args.samples if args.samples is not None else recorder.buffer_values // max(len(names), 1)
    named = table.board.values_of(args.trigger_field) if args.trigger_field is not None else None
    settings = CaptureSettings(
        channels=names,
        samples=samples,
        divider=args.divider,
        trigger=args.trigger,
        trigger_field=args.trigger_field,
        level=args.level,
        edge=args.edge,
        mask=parse_bits(args.bits, named if isinstance(named, BitSet) else None, args.trigger_field),
        pre_trigger_percent=args.pre,
    )
    try:
        check_settings(settings, table)
    except (CaptureError, UnknownNameError, FieldNameError) as error:
        raise UsageError(str(error)) from None
    return settings


class ProgressLine:
    """The recorder's progress on stderr: one line rewritten in place on a terminal, a line per
    change of state otherwise."""

    def __init__(self, total: int) -> None:
        self.total = total
        self.in_place = sys.stderr.isatty()
        self._last_state: str | None = None

    def __call__(self, status: Progress) -> None:
        if status.state == "armed":
            text = f"armed: waiting for the trigger ({status.samples_taken} samples taken)"
        elif status.state == "triggered":
            done = self.total - status.samples_left
            text = f"triggered: {done}/{self.total} samples"
        else:
            text = status.state
        if self.in_place:
            sys.stderr.write(f"\r\x1b[K{text}")
            if status.state == "done":
                sys.stderr.write("\n")
            sys.stderr.flush()
        elif status.state != self._last_state:
            progress(text)
        self._last_state = status.state


def run(args: argparse.Namespace) -> int:
    from boardproto.cia301 import NmtCommand

    table = load_table(args)
    settings = settings_from(args, table)
    period_s = RunDescription.from_arguments(args, table).rig.cycle_us(table) * 1e-6
    with open_bus(args) as bus, board_node(args, bus, table, writes=True) as node:
        # The board's TPDOs (7 a cycle at 1 kHz by default) are nothing to this command: on a
        # slow host they would queue ahead of the SDO answers it polls the recorder with.
        node.receive_only_answers()
        recorder = RecorderClient(node, table)
        try:
            recorder.configure(settings)
        except SdoTimeoutError as error:
            raise SdoTimeoutError(f"{error}; {silent_hint(node.node_id)}") from error
        from hilrig.engine.realtime import SyncProducer

        sync = SyncProducer(node.send_sync, args.sync_period_ms / 1e3) if args.sync_period_ms else None
        if args.nmt_start:
            node.nmt(NmtCommand.START)
        with sync if sync is not None else contextlib.nullcontext():
            recorder.arm()
            try:
                recorder.wait_until_done(timeout_s=args.timeout, on_progress=ProgressLine(settings.samples))
            except KeyboardInterrupt:
                progress("\ninterrupted: the recorder is disarmed, nothing written")
                raise
            if sync is not None and sync.error is not None:
                raise RigError(f"sending SYNC failed: {sync.error}")
        recording = recorder.upload()
    write_csv(recording, table, args.csv, period_s=period_s)
    written = [str(args.csv)]
    if args.rrd is not None:
        write_rrd(recording, table, args.rrd, period_s=period_s)
        written.append(str(args.rrd))
    trigger_cycle = recording.cycle_of(recording.trigger_sample)
    print(
        f"{recording.sample_count} samples of {len(recording.channels)} fields, cycles "
        f"{recording.cycle_of(0)}..{recording.cycle_of(recording.sample_count - 1)} "
        f"(every {recording.divider}), trigger at cycle {trigger_cycle}: {', '.join(written)}"
    )
    if recording.periods_skipped:
        progress("warning: the board skipped control periods while recording: cycle numbers are approximate")
    return 0


COMMANDS = (
    Command(
        name="capture",
        help="record fields on the board every cycle (its recorder), then upload them",
        description="Record board fields on the board itself, every control cycle (or every N-th),\n"
        "around a trigger, then upload the recording by SDO block transfer: fields no PDO\n"
        "carries, at cycle resolution, without loading the bus while it runs.\n\n"
        "  hilrig capture motor_velocity joint_torque --samples 2000 -o step.csv --rrd step.rrd\n"
        "  hilrig capture motor_velocity output_velocity --trigger level \\\n"
        "      --trigger-field velocity_setpoint --level 1.0 --edge rising --pre 20\n"
        "  hilrig capture motor_current fault_flags --trigger flag --trigger-field fault_flags \\\n"
        "      --bits command_watchdog --pre 50\n"
        "  hilrig capture motor_velocity --nmt-start --sync-period-ms 1   # a board with no master\n\n"
        "The recorder's settings are written to the board over SDO: a board that is not the\n"
        "table's (0x1018 vendor id and product code) is refused first (--force: not).\n"
        "Ctrl-C while waiting disarms the recorder and writes nothing. The CSV has a row per\n"
        "sample: the board's cycle number, cycle * --period-us in seconds, one column per field\n"
        "headed 'name [unit]'.",
        configure=configure,
        run=run,
    ),
)
