"""`hilrig view TRACE [--dashboard NAME] [--web [PORT]]`: a saved trace in the Rerun viewer."""

from __future__ import annotations

import argparse
import signal
from pathlib import Path
from types import FrameType

from hilrig.cli.common import Command, UsageError, existing_file, positive_int, progress

DEFAULT_DASHBOARD = "overview"


def configure(parser: argparse.ArgumentParser) -> None:
    from hilrig.trace import DEFAULT_GRPC_PORT, DEFAULT_WEB_PORT

    parser.add_argument(
        "trace",
        type=existing_file("trace", "a .rrd from `hilrig sim`, a scenario or `hilrig replay --trace`"),
        nargs="?",
        metavar="TRACE.rrd",
        help="the recording to open",
    )
    parser.add_argument(
        "-d",
        "--dashboard",
        default=DEFAULT_DASHBOARD,
        metavar="NAME",
        help=f"the layout to show (default: {DEFAULT_DASHBOARD}; --list names them all)",
    )
    parser.add_argument("--list", action="store_true", help="print the dashboards' names and exit")
    parser.add_argument(
        "--web",
        nargs="?",
        const=DEFAULT_WEB_PORT,
        type=positive_int,
        metavar="PORT",
        help=f"serve the web viewer on 127.0.0.1:PORT (default {DEFAULT_WEB_PORT}) instead of a native "
        "window, and print the page to open (no display needed)",
    )
    parser.add_argument(
        "--grpc-port",
        type=positive_int,
        default=DEFAULT_GRPC_PORT,
        metavar="PORT",
        help=f"with --web: the port the recording is served from (default {DEFAULT_GRPC_PORT})",
    )


def run(args: argparse.Namespace) -> int:
    from hilrig.errors import RigError
    from hilrig.trace import DEFAULT_WEB_PORT, blueprint_names, open_trace

    names = blueprint_names()
    if args.list:
        print("\n".join(names))
        return 0
    if args.dashboard not in names:
        from hilrig.table import unknown_name

        raise UsageError(str(unknown_name("dashboard", args.dashboard, names)))
    trace: Path | None = args.trace
    if trace is None:
        raise UsageError("name the trace to open: hilrig view TRACE.rrd (or --list the dashboards)")
    if trace.suffix != ".rrd":
        raise UsageError(f"{trace}: expected a Rerun recording (.rrd)")
    try:
        process = open_trace(
            trace,
            args.dashboard,
            web=args.web is not None,
            web_port=args.web or DEFAULT_WEB_PORT,
            grpc_port=args.grpc_port,
        )
    except OSError as error:  # a port in use
        raise RigError(str(error)) from None
    assert not isinstance(process, list)
    if args.web is None:
        progress(f"view: {trace} in a native viewer ({args.dashboard}); close its window to end")
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


def _interrupt(signum: int, frame: FrameType | None) -> None:
    raise KeyboardInterrupt


COMMANDS = (
    Command(
        name="view",
        help="open a trace (.rrd) in the Rerun viewer with one of the dashboards",
        description="Open a trace the rig wrote (hilrig sim, a scenario, hilrig replay --trace)\n"
        "in the Rerun viewer with a dashboard: overview, tuning, thermal, faults, and\n"
        "robot for a robot's trace (hilrig sim --modules: the chain in 3D, every\n"
        "joint's commanded vs measured angle) (--list). --web serves the web viewer\n"
        "instead of a window, for a machine without a display; open the page it\n"
        "prints (from another machine, forward both ports:\n"
        "ssh -L 9090:127.0.0.1:9090 -L 9876:127.0.0.1:9876 host).\n\n"
        "  hilrig view out/demo/trace.rrd\n"
        "  hilrig view out/demo/trace.rrd --dashboard tuning --web\n"
        "  hilrig view out/robot/trace.rrd --dashboard robot",
        configure=configure,
        run=run,
    ),
)
