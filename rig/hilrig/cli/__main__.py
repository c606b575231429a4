"""`python -m hilrig.cli ...` is the `hilrig` console script."""

import sys

from hilrig.cli import main

sys.exit(main())
