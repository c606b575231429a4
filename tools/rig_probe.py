#!/usr/bin/env python3
"""The Rig's own cost per lockstep cycle, natively (`hilrig.apps.bench.probe`, whose --help says
the modes): `make bench` counts it under callgrind, as it counts a baseline commit's
tools/rig_probe.py. The rig and boardproto of this tree come first on the path, whatever is
installed."""

import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(REPO / "rig"), str(REPO / "protocol")]

from hilrig.apps.bench.probe import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main())
