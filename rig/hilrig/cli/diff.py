"""`hilrig diff BASE.rrd CAND.rrd`: what changed since the last good run, as one recording.

Exit codes as `diff` has them: 0 the runs agree, 1 they differ (the first divergence is printed)
or a recording cannot be read whole, 2 a file is missing or no recording at all.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from hilrig.cli.common import Command, UsageError, existing_file, port, progress
from hilrig.cli.files import ArgKind, kind, output_file
from hilrig.cli.view import sniff_rrd

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


def configure(parser: argparse.ArgumentParser) -> None:
    from hilrig.observe.diff import Tolerance
    from hilrig.observe.sinks import DEFAULT_WEB_PORT

    recording = existing_file(
        "trace",
        "a .rrd from `hilrig sim`, a scenario or `hilrig replay --trace`",
        suffixes=(".rrd",),
        sniff=sniff_rrd,
    )
    parser.add_argument("base", type=recording, metavar="BASE.rrd", help="the last good run")
    parser.add_argument("cand", type=recording, metavar="CAND.rrd", help="the run to compare with it")
    parser.add_argument(
        "-o",
        "--out",
        type=output_file("comparison", suffixes=(".rrd",)),
        default=None,
        metavar="OUT.rrd",
        help=f"the comparison's recording (default: {DEFAULT_OUT_NAME} beside CAND)",
    )
    parser.add_argument(
        "--atol",
        type=non_negative_float,
        default=Tolerance.atol,
        help=f"absolute tolerance: values this close count as equal (default {Tolerance.atol:g})",
    )
    parser.add_argument(
        "--rtol",
        type=non_negative_float,
        default=Tolerance.rtol,
        help=f"relative tolerance, of the larger magnitude (default {Tolerance.rtol:g})",
    )
    parser.add_argument(
        "--ignore",
        action="append",
        default=[],
        metavar="GLOB",
        help="leave out the series whose path or name matches (repeatable), e.g. events a wall "
        "clock stamps: --ignore '/events/nmt'",
    )
    parser.add_argument(
        "--view",
        action="store_true",
        help="open the comparison in a native viewer with the diff dashboard when done",
    )
    parser.add_argument(
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
        help="compare two traces: the first cycle a field differs, and one recording of both",
        description="Compare two traces of the rig (a good run and a new one) cycle by cycle:\n"
        "print the first cycle where any series differs beyond the tolerance (and the next\n"
        "few), and write one recording with both runs on the same cycle timeline (BASE under\n"
        "/base, CAND under /cand, CAND - BASE under /diff) that opens with the diff\n"
        "dashboard. Exit 0 when the runs agree, 1 when they differ (or a recording is cut\n"
        "short), 2 for a file that is missing or no recording.\n\n"
        "  hilrig diff out/good/trace.rrd out/demo/trace.rrd\n"
        "  hilrig diff base.rrd cand.rrd --atol 1e-4 -o out/diff.rrd --web",
        configure=configure,
        run=run,
    ),
)
