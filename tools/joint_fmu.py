#!/usr/bin/env python3
"""`make build`'s FMU of the demo joint (`hilrig.apps.joint_fmu`, whose doc says what it writes):

    .venv/bin/python tools/joint_fmu.py [--out build/fmu]

The rig and boardproto of this tree come first on the path, whatever is installed."""

import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(REPO / "rig"), str(REPO / "protocol")]

from hilrig.apps.joint_fmu import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main())
