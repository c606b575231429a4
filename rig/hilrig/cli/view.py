"""`hilrig view TRACE [--dashboard NAME] [--web [PORT]]`: a saved trace in the Rerun viewer."""

from __future__ import annotations

import argparse
import signal
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING

from hilrig.cli.common import (
    NO_DISPLAY,
    Command,
    UsageError,
    add_table_option,
    existing_file,
    has_display,
    port,
    progress,
)

if TYPE_CHECKING:
    import rerun.blueprint as rrb

    from hilrig.observe.reader import Trace, TraceBoard
    from hilrig.table import RigTable

DEFAULT_DASHBOARD = "overview"
RRD_MAGIC = b"RRF"
"""How a Rerun recording starts (RRF2 today, RRF0/RRF1 before)."""


def sniff_rrd(path: Path) -> str | None:
    with path.open("rb") as file:
        start = file.read(len(RRD_MAGIC))
    return None if start == RRD_MAGIC else "is not a Rerun recording (it does not start with RRF)"


def configure(parser: argparse.ArgumentParser) -> None:
    from hilrig.observe.sinks import DEFAULT_GRPC_PORT, DEFAULT_WEB_PORT

    parser.add_argument(
        "trace",
        type=existing_file(
            "trace",
            "a .rrd from `hilrig sim`, a scenario or `hilrig replay --trace`",
            suffixes=(".rrd",),
            sniff=sniff_rrd,
        ),
        nargs="?",
        metavar="TRACE.rrd",
        help="the recording to open",
    )
    parser.add_argument(
        "-d",
        "--dashboard",
        default=None,
        metavar="NAME",
        help=f"the layout to show (default: diff for `hilrig diff`'s, robot for a robot's, else the "
        f"one the trace recorded: {DEFAULT_DASHBOARD} for the demo joint, board (generated from the "
        "table and plant) for another board; --list names them all)",
    )
    add_table_option(parser)  # for a trace that records no table: one recorded wins
    parser.add_argument("--list", action="store_true", help="print the dashboards' names and exit")
    parser.add_argument(
        "--check",
        action="store_true",
        help="open nothing: say which series the dashboards name that the trace has no data for "
        "(every dashboard made for the trace, or the one given with --dashboard); exit 1 if any",
    )
    parser.add_argument(
        "--web",
        nargs="?",
        const=DEFAULT_WEB_PORT,
        type=port,
        metavar="PORT",
        help=f"serve the web viewer on 127.0.0.1:PORT (default {DEFAULT_WEB_PORT}) instead of a native "
        "window, and print the page to open (no display needed)",
    )
    parser.add_argument(
        "--grpc-port",
        type=port,
        default=DEFAULT_GRPC_PORT,
        metavar="PORT",
        help=f"with --web: the port the recording is served from (default {DEFAULT_GRPC_PORT})",
    )


def run(args: argparse.Namespace) -> int:
    from hilrig.observe.blueprints import blueprint_names

    names = blueprint_names()
    if args.list:
        print("\n".join(names))
        return 0
    if args.dashboard is not None and args.dashboard not in names:
        from hilrig.table import unknown_name

        raise UsageError(str(unknown_name("dashboard", args.dashboard, names)))
    trace: Path | None = args.trace
    if trace is None:
        raise UsageError("name the trace to open: hilrig view TRACE.rrd (or --list the dashboards)")
    if trace.suffix != ".rrd":
        raise UsageError(f"{trace}: expected a Rerun recording (.rrd)")
    table = _given_table(args)
    if args.check:
        return _check(trace, args.dashboard, table)
    if args.web is None and not has_display():  # before the trace is read: say it at once
        raise UsageError(f"{NO_DISPLAY}: add --web to serve the web viewer and open the page it prints")
    dashboard, blueprint = trace_dashboard(trace, args.dashboard, table)
    return show(trace, dashboard, web_port=args.web, grpc_port=args.grpc_port, blueprint=blueprint)


def _given_table(args: argparse.Namespace) -> RigTable | None:
    """The table --table names (as the CLI resolves it), for a trace that records none."""
    if getattr(args, "table", None) is None:
        return None
    from hilrig.cli.common import load_table

    return load_table(args)


def trace_dashboard(
    trace: Path, name: str | None, table: RigTable | None = None
) -> tuple[str, rrb.Blueprint]:
    """The dashboard to open `trace` with (`name`, else its own: `default_dashboard`) and its
    blueprint, built for the table the trace records (else `table`, else the default board's);
    the generated one reads the whole trace, to show every series it holds."""
    from hilrig.observe.blueprints import load_blueprint
    from hilrig.observe.dashboard_check import trace_blueprint
    from hilrig.observe.paths import GENERATED_DASHBOARD

    chosen, board = default_dashboard(trace, table)
    dashboard = name or chosen
    board_table = _table_of(trace, board, table)
    if dashboard == GENERATED_DASHBOARD or dashboard == "robot":
        progress(f"view: reading {trace}")
        return dashboard, trace_blueprint(dashboard, _read(trace), board_table)
    return dashboard, load_blueprint(dashboard, board_table)


def default_dashboard(trace: Path, table: RigTable | None = None) -> tuple[str, TraceBoard | None]:
    """The dashboard made for the kind of recording: `diff` for a comparison (`hilrig diff`),
    `robot` for a robot's trace, else the one its board opens with (`own_dashboard`), and the
    board the trace records. Looks at what it logs before its first data."""
    import rerun as rr

    from hilrig.observe.dashboard_check import own_dashboard
    from hilrig.observe.paths import DIFF_BASE_ROOT, DIFF_CAND_ROOT, DIFF_ROOT, MODULES_ROOT, ROBOT_ROOT
    from hilrig.observe.reader import TraceBoard, _columns, board_property_path

    board: TraceBoard | None = None
    try:
        for chunk in rr.chunk.RrdReader(trace).stream():
            if chunk.entity_path == board_property_path():
                board = TraceBoard.from_columns(_columns(chunk.to_record_batch()))
                continue
            root = "/" + chunk.entity_path.lstrip("/").split("/", 1)[0]
            if root in (DIFF_BASE_ROOT, DIFF_CAND_ROOT, DIFF_ROOT):
                return "diff", board
            if root in (MODULES_ROOT, ROBOT_ROOT):
                return "robot", board
            if not chunk.is_static:
                break
    except RuntimeError as error:  # Rerun's reader: a cut-off or foreign file
        raise _unreadable(trace, error) from None
    return own_dashboard(board, _table_of(trace, board, table)), board


def _table_of(trace: Path, board: TraceBoard | None, table: RigTable | None) -> RigTable:
    """`trace_table`, a recorded table that does not load a one-line error."""
    from boardproto import TableError
    from hilrig.errors import LogFileError
    from hilrig.observe.dashboard_check import trace_table

    try:
        return trace_table(board, table)
    except TableError as error:
        raise LogFileError(f"{trace}: the table it records does not load ({error})") from None


def _unreadable(trace: Path, error: RuntimeError) -> Exception:
    from hilrig.errors import LogFileError, one_line

    return LogFileError(f"{trace}: Rerun cannot read this recording ({one_line(error)})")


def _read(trace: Path) -> Trace:
    from hilrig.observe.reader import Trace

    try:
        return Trace.read(trace)
    except RuntimeError as error:  # rerun's reader: a cut-off or foreign file
        raise _unreadable(trace, error) from None


def show(
    trace: Path,
    dashboard: str,
    *,
    web_port: int | None,
    grpc_port: int | None,
    blueprint: rrb.Blueprint | None = None,
) -> int:
    """`trace` in a native viewer (web_port None) or served to the web viewer, with `dashboard`
    (`blueprint`: it built for the trace's board; None: the named one for the default table);
    returns when the person closes it (or presses Ctrl-C)."""
    from hilrig.errors import RigError
    from hilrig.observe.sinks import DEFAULT_GRPC_PORT, DEFAULT_WEB_PORT
    from hilrig.observe.viewer import open_trace

    if web_port is None and not has_display():
        raise UsageError(f"{NO_DISPLAY}: add --web to serve the web viewer and open the page it prints")
    try:
        process = open_trace(
            trace,
            blueprint if blueprint is not None else dashboard,
            web=web_port is not None,
            web_port=web_port or DEFAULT_WEB_PORT,
            grpc_port=grpc_port or DEFAULT_GRPC_PORT,
        )
    except OSError as error:  # a port in use
        raise RigError(str(error)) from None
    assert not isinstance(process, list)
    if web_port is None:
        progress(f"view: {trace} in a native viewer ({dashboard}); close its window to end")
    previous = signal.signal(signal.SIGTERM, _interrupt)
    try:
        return process.wait()
    except KeyboardInterrupt:
        return 0  # the person is done looking
    finally:
        signal.signal(signal.SIGTERM, previous)
        # The viewer runs in a process group of its own: Ctrl-C reached only us, so end it too.
        process.terminate()
        process.wait()


def _check(trace: Path, dashboard: str | None, table: RigTable | None) -> int:
    """Every series the dashboards name, looked up in the trace; the gaps on stdout."""
    from hilrig.observe.blueprints import dashboards

    dashboards()  # importable from a checkout on PYTHONPATH alone too
    from hilrig.observe.dashboard_check import fitting_dashboards, trace_blueprint, trace_gaps

    progress(f"view: reading {trace}")
    recording = _read(trace)
    board_table = _table_of(trace, recording.board, table)
    if dashboard:
        checked = {dashboard: trace_blueprint(dashboard, recording, board_table)}
    else:
        checked = fitting_dashboards(recording, board_table)
    gaps = trace_gaps(recording, checked)
    for gap in gaps:
        print(gap)
    names = ", ".join(checked)
    if gaps:
        progress(f"view: {trace}: {len(gaps)} series named by {names} without data")
        return 1
    print(f"{trace}: every series {names} name has data")
    return 0


def _interrupt(signum: int, frame: FrameType | None) -> None:
    raise KeyboardInterrupt


COMMANDS = (
    Command(
        name="view",
        help="open a trace (.rrd) in the Rerun viewer with one of the dashboards",
        description="Open a trace the rig wrote (hilrig sim, a scenario, hilrig replay --trace)\n"
        "in the Rerun viewer with a dashboard: the demo joint's overview, tuning, thermal,\n"
        "faults, bus; robot for a robot's trace (hilrig sim --modules: the chain in 3D, every\n"
        "joint's commanded vs measured angle); board, generated for any board from the table\n"
        "and plant its trace records (--list). A trace records its board's table; --table is\n"
        "for a trace that records none. --web serves the web viewer\n"
        "instead of a window, for a machine without a display; open the page it\n"
        "prints (from another machine, forward both ports:\n"
        "ssh -L 9090:127.0.0.1:9090 -L 9876:127.0.0.1:9876 host).\n\n"
        "  hilrig view out/demo/trace.rrd\n"
        "  hilrig view out/demo/trace.rrd --dashboard tuning --web\n"
        "  hilrig view out/robot/trace.rrd --dashboard robot\n"
        "  hilrig view out/demo/trace.rrd --check   # which plotted series have no data",
        configure=configure,
        run=run,
    ),
)
