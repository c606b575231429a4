"""`hilrig diff BASE.rrd CAND.rrd`: what changed since the last good run, as one recording; `hilrig
diff BASE.log CAND.blf`: the first frame at which two bus logs of any format differ.

Exit codes as `diff` has them: 0 the runs agree, 1 they differ (the first divergence is printed)
or a file cannot be read whole, 2 a file is missing, of no known kind, or a trace beside a log.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from hilrig.cli.common import Command, UsageError, existing_file, port, progress
from hilrig.cli.files import ArgKind, kind, output_file, unreadable_reason
from hilrig.cli.view import sniff_rrd
from hilrig.session.logformats import BLF_CLOCKS, DEFAULT_BLF_CLOCK, LOG_FORMATS

TRACE_SUFFIX = ".rrd"
INPUT_HINT = "a .rrd from `hilrig sim`, a scenario or `hilrig replay --trace`, or a bus log"

DEFAULT_OUT_NAME = "diff.rrd"


@kind(ArgKind("number", out_of_range="-1"))
def non_negative_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}") from None
    if not 0.0 <= value < float("inf"):
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, got {text}")
    return value


@kind(ArgKind("input file", (TRACE_SUFFIX, *LOG_FORMATS), sniffed=True))
def recording_or_log(text: str) -> Path:
    """A trace (.rrd, its content checked) or a bus log (its format judged when it is read)."""
    if text.lower().endswith(TRACE_SUFFIX):
        return existing_file("trace", INPUT_HINT, suffixes=(TRACE_SUFFIX,), sniff=sniff_rrd)(text)
    reason = unreadable_reason(Path(text))
    if reason is not None:
        raise argparse.ArgumentTypeError(f"{text} {reason}; give {INPUT_HINT} ({', '.join(LOG_FORMATS)})")
    return Path(text)


def bus_log_id(text: str) -> int:
    try:
        value = int(text, 16)
    except ValueError:
        value = -1
    if not 0 <= value <= 0x1FFF_FFFF:
        raise argparse.ArgumentTypeError(f"expected a CAN id in hex (0x optional, e.g. 0x710), got {text!r}")
    return value


def configure(parser: argparse.ArgumentParser) -> None:
    from hilrig.apps.log_diff import DEFAULT_TIME_TOLERANCE_S, TimeRule
    from hilrig.observe.diff import Tolerance
    from hilrig.observe.sinks import DEFAULT_WEB_PORT

    parser.add_argument(
        "base", type=recording_or_log, metavar="BASE", help="the last good run: .rrd or a bus log"
    )
    parser.add_argument(
        "cand", type=recording_or_log, metavar="CAND", help="the run to compare with it, of the same kind"
    )
    logs = parser.add_argument_group("bus logs")
    logs.add_argument(
        "--times",
        choices=[rule.value for rule in TimeRule],
        default=TimeRule.IGNORE.value,
        help="frame times: ignore them (default), compare each frame's time since its log's first "
        "frame (relative), or the UTC times themselves (absolute: a log and its conversion)",
    )
    logs.add_argument(
        "--time-tolerance",
        type=non_negative_float,
        default=DEFAULT_TIME_TOLERANCE_S,
        metavar="S",
        help=f"--times: times this close count as equal (default {DEFAULT_TIME_TOLERANCE_S:g} s)",
    )
    logs.add_argument(
        "--ignore-id",
        action="append",
        type=bus_log_id,
        default=[],
        metavar="ID",
        help="leave out the frames of this CAN id in both logs (repeatable), e.g. heartbeats "
        "that follow the wall clock: --ignore-id 0x710",
    )
    logs.add_argument(
        "--blf-clock",
        choices=BLF_CLOCKS,
        default=DEFAULT_BLF_CLOCK,
        help="a .blf's header start time: local time as CANoe writes it (default), or utc as "
        "python-can's BLFWriter does (matters with --times absolute)",
    )
    traces = parser.add_argument_group("traces (.rrd)")
    traces.add_argument(
        "-o",
        "--out",
        type=output_file("comparison", suffixes=(".rrd",)),
        default=None,
        metavar="OUT.rrd",
        help=f"the comparison's recording (default: {DEFAULT_OUT_NAME} beside CAND)",
    )
    traces.add_argument(
        "--atol",
        type=non_negative_float,
        default=Tolerance.atol,
        help=f"absolute tolerance: values this close count as equal (default {Tolerance.atol:g})",
    )
    traces.add_argument(
        "--rtol",
        type=non_negative_float,
        default=Tolerance.rtol,
        help=f"relative tolerance, of the larger magnitude (default {Tolerance.rtol:g})",
    )
    traces.add_argument(
        "--ignore",
        action="append",
        default=[],
        metavar="GLOB",
        help="leave out the series whose path or name matches (repeatable), e.g. events a wall "
        "clock stamps: --ignore '/events/nmt'",
    )
    traces.add_argument(
        "--view",
        action="store_true",
        help="open the comparison in a native viewer with the diff dashboard when done",
    )
    traces.add_argument(
        "--web",
        nargs="?",
        const=DEFAULT_WEB_PORT,
        type=port,
        metavar="PORT",
        help=f"serve it to the web viewer on 127.0.0.1:PORT (default {DEFAULT_WEB_PORT}) when done",
    )


def _read(path: Path, what: str) -> object:
    from hilrig.errors import LogFileError, one_line
    from hilrig.observe.reader import Trace

    try:
        return Trace.read(path)
    except RuntimeError as error:  # Rerun's reader: a cut-off or foreign file
        raise LogFileError(f"{what} {path}: Rerun cannot read this recording ({one_line(error)})") from None


def run(args: argparse.Namespace) -> int:
    traces = [path.name.lower().endswith(TRACE_SUFFIX) for path in (args.base, args.cand)]
    if traces[0] != traces[1]:
        raise UsageError("BASE and CAND must be of one kind: two .rrd traces or two bus logs")
    if not traces[0]:
        return _run_logs(args)
    from hilrig.observe.blueprints import load_blueprint
    from hilrig.observe.diff import Tolerance, compare, write_comparison
    from hilrig.observe.reader import Trace
    from hilrig.table import RigTable

    table = RigTable.load()
    progress(f"diff: reading {args.base} and {args.cand}")
    base, cand = _read(args.base, "BASE"), _read(args.cand, "CAND")
    assert isinstance(base, Trace) and isinstance(cand, Trace)
    tolerance = Tolerance(args.atol, args.rtol)
    comparison = compare(base, cand, tolerance, names=series_names(table, base, cand), ignore=args.ignore)
    for line in comparison.summary():
        print(line)
    if args.view and args.web is None:
        from hilrig.cli.common import NO_DISPLAY, has_display

        if not has_display():  # before the work: say it at once
            raise UsageError(f"{NO_DISPLAY}: add --web to serve the web viewer and open the page it prints")
    out: Path = args.out if args.out is not None else args.cand.parent / DEFAULT_OUT_NAME
    if out.resolve() in (args.base.resolve(), args.cand.resolve()):
        raise UsageError(f"--out {out} would overwrite a recording being compared; name another file")
    write_comparison(comparison, base, cand, out, load_blueprint("diff", table))
    print(f"wrote {out}: `hilrig view {out}` shows it with the diff dashboard")
    if args.view or args.web is not None:
        from hilrig.cli.view import show

        show(out, "diff", web_port=args.web, grpc_port=None)
    return 0 if comparison.same else 1


def _run_logs(args: argparse.Namespace) -> int:
    from hilrig.apps.log_diff import TimeRule, compare_logs
    from hilrig.session.buslog import read_log

    if args.out is not None or args.view or args.web is not None:
        raise UsageError("--out, --view and --web are for traces: two bus logs are compared in text")
    progress(f"diff: reading {args.base} and {args.cand}")
    with (
        read_log(args.base, blf_clock=args.blf_clock) as base,
        read_log(args.cand, blf_clock=args.blf_clock) as cand,
    ):
        comparison = compare_logs(
            base,
            cand,
            times=TimeRule(args.times),
            tolerance_s=args.time_tolerance,
            ignore_ids=frozenset(args.ignore_id),
        )
    for line in comparison.summary():
        print(line)
    return 0 if comparison.same else 1


def series_names(table: object, *traces: object) -> dict[str, str]:
    """Entity path -> the name a person knows it by: a board field's name, with "module N" in
    front in a robot's trace; the path itself for everything else."""
    from hilrig.observe.paths import MODULES_ROOT, entity_paths
    from hilrig.observe.reader import Trace

    by_path = {path: name for name, path in entity_paths(table).items()}  # type: ignore[arg-type]
    names: dict[str, str] = {}
    for trace in traces:
        assert isinstance(trace, Trace)
        for path in (*trace.scalars, *trace.texts):
            if path in by_path:
                names[path] = by_path[path]
            elif path.startswith(MODULES_ROOT + "/"):
                _, _, node, rest = path.split("/", 3)
                if "/" + rest in by_path:
                    names[path] = f"module {node} {by_path['/' + rest]}"
    return names


COMMANDS = (
    Command(
        name="diff",
        help="compare two traces (the first cycle a field differs, one recording of both) or two bus logs",
        description="Compare two traces of the rig (a good run and a new one) cycle by cycle:\n"
        "print the first cycle where any series differs beyond the tolerance (and the next\n"
        "few), and write one recording with both runs on the same cycle timeline (BASE under\n"
        "/base, CAND under /cand, CAND - BASE under /diff) that opens with the diff\n"
        "dashboard. Exit 0 when the runs agree, 1 when they differ (or a recording is cut\n"
        "short), 2 for a file that is missing or no recording.\n\n"
        "Two bus logs (any format: .log, .asc, .blf, .mf4, .csv, .trc, and what else python-can\n"
        "reads; BASE and CAND may differ in format) are compared frame by frame: identifier,\n"
        "kind, length and bytes, times ignored unless --times says how to compare them. It\n"
        "prints the first frame that differs, or where one log ends early, with both frames;\n"
        "exit 0 when every frame agrees, 1 at the first difference.\n\n"
        "  hilrig diff out/good/trace.rrd out/demo/trace.rrd\n"
        "  hilrig diff base.rrd cand.rrd --atol 1e-4 -o out/diff.rrd --web\n"
        "  hilrig diff good/bus.log new/bus.mf4 --ignore-id 0x710    # heartbeats aside\n"
        "  hilrig diff bus.log bus.blf --times absolute               # a conversion, time for time",
        configure=configure,
        run=run,
    ),
)
