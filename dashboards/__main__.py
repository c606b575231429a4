"""Open a saved trace with a named blueprint: python -m dashboards NAME TRACE.rrd [--web [PORT]]."""

from __future__ import annotations

import argparse

from dashboards.joint import BLUEPRINTS
from hilrig.trace import DEFAULT_WEB_PORT, open_trace


def main() -> int:
    parser = argparse.ArgumentParser(prog="python -m dashboards", description=__doc__)
    parser.add_argument("blueprint", choices=sorted(BLUEPRINTS))
    parser.add_argument("trace", help="a .rrd the rig wrote")
    parser.add_argument("--web", nargs="?", const=DEFAULT_WEB_PORT, type=int, metavar="PORT",
                        help=f"serve the web viewer on localhost (default port {DEFAULT_WEB_PORT})")
    args = parser.parse_args()
    process = open_trace(args.trace, args.blueprint, web=args.web is not None,
                         web_port=args.web or DEFAULT_WEB_PORT)
    assert not isinstance(process, list)
    return process.wait()


if __name__ == "__main__":
    raise SystemExit(main())
