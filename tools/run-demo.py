"""The `make run` demo: `hilrig sim` (rig/hilrig/apps/demo.py) inside tools/with-vcan.

The firmware runs in lockstep on a private vcan bus against the rig's joint physics: a velocity
then a torque profile, a summary, and the bus log in --out.

    python tools/run-demo.py --out out/demo [--scenario FILE.py]
"""

from __future__ import annotations

import os
import sys

from hilrig.cli import main

if __name__ == "__main__":
    print(f"bus path: {os.environ.get('HIL_BUS_PATH', 'unknown')}", flush=True)
    sys.exit(main(["sim", *sys.argv[1:]]))
