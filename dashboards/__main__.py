"""`python -m dashboards NAME TRACE.rrd [--web [PORT]]`: the older spelling of
`hilrig view TRACE.rrd --dashboard NAME [--web [PORT]]`, kept so earlier notes still work."""

from __future__ import annotations

import sys

from hilrig.cli import main

if __name__ == "__main__":
    if len(sys.argv) >= 3 and not sys.argv[1].startswith("-"):
        name, trace, *rest = sys.argv[1:]
        raise SystemExit(main(["view", trace, "--dashboard", name, *rest]))
    raise SystemExit(main(["view", *sys.argv[1:]]))
