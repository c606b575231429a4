"""`python -m hilrig ...` is the `hilrig` console script (for a venv whose bin/ is not on PATH)."""

import sys

from hilrig.cli import main

sys.exit(main())
