"""`make screenshots`: one picture per dashboard for the README, made from real runs, never by hand.

    tools/screenshots.py --demo out/demo/trace.rrd --robot out/robot/trace.rrd \
        --other out/demo-seed2/trace.rrd --out docs/dashboards

Each dashboard is shown in the Rerun web viewer in headless Chromium on the trace it is made for
(`hilrig.apps.screenshots`): the joint's five on the demo trace, `robot` on the robot's, `diff` on
`hilrig diff` of the demo and a run with another seed. A dashboard with a problem (a view hidden
or in error, nothing drawn, a console error) is named and the command exits 1; the pictures of
the others are still written.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

from hilrig.apps.screenshots import browser_missing, shoot
from hilrig.cli import main as hilrig


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--demo", type=Path, required=True, help="the demo's trace (make run)")
    parser.add_argument("--robot", type=Path, required=True, help="a robot's trace (make run ROBOT=4)")
    parser.add_argument("--other", type=Path, required=True, help="a second demo run, for the diff")
    parser.add_argument("--out", type=Path, required=True, help="where the pictures go")
    args = parser.parse_args(argv)
    missing = [str(p) for p in (args.demo, args.robot, args.other) if not p.is_file()]
    if missing:
        print(f"screenshots: no trace at {', '.join(missing)}: `make screenshots` runs them", file=sys.stderr)
        return 2
    if (why := browser_missing()) is not None:
        print(f"screenshots: {why}", file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    problems: list[str] = []
    with tempfile.TemporaryDirectory(prefix="hilrig-screenshots-") as work:
        scratch = Path(work)
        comparison = scratch / "diff.rrd"
        hilrig(["diff", str(args.demo), str(args.other), "-o", str(comparison)])  # 1: they differ
        for trace in (args.demo, args.robot, comparison):
            problems += shoot(trace, args.out, scratch / trace.stem)
    for problem in problems:
        print(f"screenshots: {problem}", file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
