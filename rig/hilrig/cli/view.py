"""`hilrig view TRACE [--dashboard NAME] [--web [PORT]]`: a saved trace in the Rerun viewer."""

from __future__ import annotations

import argparse
import signal
from pathlib import Path
from types import FrameType

from hilrig.cli.common import (
    NO_DISPLAY,
    Command,
    UsageError,
    existing_file,
    has_display,
    port,
    progress,
)

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
        help=f"the layout to show (default: diff for `hilrig diff`'s, robot for a robot's, else "
        f"{DEFAULT_DASHBOARD}; --list names them all)",
    )
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
    if args.check:
        return _check(trace, args.dashboard)
    if args.web is None and not has_display():  # before the trace is read: say it at once
        raise UsageError(f"{NO_DISPLAY}: add --web to serve the web viewer and open the page it prints")
    dashboard = args.dashboard or default_dashboard(trace)
    return show(trace, dashboard, web_port=args.web, grpc_port=args.grpc_port)


def default_dashboard(trace: Path) -> str:
    """The dashboard made for the kind of recording: `diff` for a comparison (`hilrig diff`),
    `robot` for a robot's trace, the overview otherwise. Looks at the first entity it logs."""
    import rerun as rr

    from hilrig.observe.paths import DIFF_BASE_ROOT, DIFF_CAND_ROOT, DIFF_ROOT, MODULES_ROOT, ROBOT_ROOT

    try:
        for chunk in rr.chunk.RrdReader(trace).stream():
            root = "/" + chunk.entity_path.lstrip("/").split("/", 1)[0]
            if root in (DIFF_BASE_ROOT, DIFF_CAND_ROOT, DIFF_ROOT):
                return "diff"
            if root in (MODULES_ROOT, ROBOT_ROOT):
                return "robot"
            if not chunk.is_static:
                break
    except RuntimeError as error:  # Rerun's reader: a cut-off or foreign file
        from hilrig.errors import LogFileError, one_line

        raise LogFileError(f"{trace}: Rerun cannot read this recording ({one_line(error)})") from None
    return DEFAULT_DASHBOARD


def show(trace: Path, dashboard: str, *, web_port: int | None, grpc_port: int | None) -> int:
    """`trace` in a native viewer (web_port None) or served to the web viewer, with `dashboard`;
    returns when the person closes it (or presses Ctrl-C)."""
    from hilrig.errors import RigError
    from hilrig.observe.sinks import DEFAULT_GRPC_PORT, DEFAULT_WEB_PORT
    from hilrig.observe.viewer import open_trace

    if web_port is None and not has_display():
        raise UsageError(f"{NO_DISPLAY}: add --web to serve the web viewer and open the page it prints")
    try:
        process = open_trace(
            trace,
            dashboard,
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


def _check(trace: Path, dashboard: str | None) -> int:
    """Every series the dashboards name, looked up in the trace; the gaps on stdout."""
    from hilrig.observe.blueprints import dashboards

    dashboards()  # importable from a checkout on PYTHONPATH alone too
    from hilrig.errors import LogFileError, one_line
    from hilrig.observe.blueprints import load_blueprint
    from hilrig.observe.dashboard_check import fitting_dashboards, trace_gaps
    from hilrig.observe.reader import Trace

    progress(f"view: reading {trace}")
    try:
        recording = Trace.read(trace)
    except RuntimeError as error:  # rerun's reader: a cut-off or foreign file
        raise LogFileError(f"{trace}: Rerun cannot read this recording ({one_line(error)})") from None
    fitting = fitting_dashboards(recording)  # robot: for the modules the trace has
    dashboards = {dashboard: fitting.get(dashboard) or load_blueprint(dashboard)} if dashboard else fitting
    gaps = trace_gaps(recording, dashboards)
    for gap in gaps:
        print(gap)
    checked = ", ".join(dashboards)
    if gaps:
        progress(f"view: {trace}: {len(gaps)} series named by {checked} without data")
        return 1
    print(f"{trace}: every series {checked} name has data")
    return 0


def _interrupt(signum: int, frame: FrameType | None) -> None:
    raise KeyboardInterrupt


COMMANDS = (
    Command(
        name="view",
        help="open a trace (.rrd) in the Rerun viewer with one of the dashboards",
        description="Open a trace the rig wrote (hilrig sim, a scenario, hilrig replay --trace)\n"
        "in the Rerun viewer with a dashboard: overview, tuning, thermal, faults, bus, and\n"
        "robot for a robot's trace (hilrig sim --modules: the chain in 3D, every\n"
        "joint's commanded vs measured angle) (--list). --web serves the web viewer\n"
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
