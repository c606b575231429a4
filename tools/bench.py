#!/usr/bin/env python3
"""`make bench` and `make bench-baseline`: the bench app (`hilrig.apps.bench`), whose --help says
what is measured and against what."""

import sys

from hilrig.apps.bench.main import main

if __name__ == "__main__":
    sys.exit(main())
