"""Open a saved trace with a named blueprint: python -m dashboards NAME TRACE.rrd [--web [PORT]].

--web serves the web viewer on this machine (no display needed) and prints the page to open.
"""

from __future__ import annotations

import argparse
import signal
from types import FrameType

from dashboards.joint import BLUEPRINTS
from hilrig.trace import DEFAULT_GRPC_PORT, DEFAULT_WEB_PORT, open_trace


def main() -> int:
    parser = argparse.ArgumentParser(
        prog="python -m dashboards", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("blueprint", choices=sorted(BLUEPRINTS))
    parser.add_argument("trace", help="a .rrd the rig wrote")
    parser.add_argument(
        "--web",
        nargs="?",
        const=DEFAULT_WEB_PORT,
        type=int,
        metavar="PORT",
        help=f"serve the web viewer on 127.0.0.1:PORT (default {DEFAULT_WEB_PORT}) and print its URL",
    )
    parser.add_argument(
        "--grpc-port",
        type=int,
        default=DEFAULT_GRPC_PORT,
        metavar="PORT",
        help=f"with --web: the port the recording is served from (default {DEFAULT_GRPC_PORT})",
    )
    args = parser.parse_args()
    try:
        process = open_trace(
            args.trace,
            args.blueprint,
            web=args.web is not None,
            web_port=args.web or DEFAULT_WEB_PORT,
            grpc_port=args.grpc_port,
        )
    except OSError as error:  # no such trace, or a port in use
        parser.exit(2, f"python -m dashboards: {error}\n")
    assert not isinstance(process, list)
    signal.signal(signal.SIGTERM, _exit_on_sigterm)
    try:
        return process.wait()
    except KeyboardInterrupt:
        return 130
    finally:
        # The viewer has its own process group, so Ctrl-C or a kill reached only us: end it too.
        process.terminate()
        process.wait()


def _exit_on_sigterm(signum: int, frame: FrameType | None) -> None:
    raise SystemExit(128 + signum)  # unwinds through main's finally, which ends the viewer


if __name__ == "__main__":
    raise SystemExit(main())
