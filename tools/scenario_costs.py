#!/usr/bin/env python3
"""What a scenario spends outside its cycles, step by step (`hilrig.apps.bench.scenario_costs`):

tools/with-vcan -- .venv/bin/python tools/scenario_costs.py [--cycles 500] [--modules 4]
"""

import sys

from hilrig.apps.bench.scenario_costs import main

if __name__ == "__main__":
    sys.exit(main())
