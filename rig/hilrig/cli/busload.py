"""`hilrig bus-load`: will this PDO mapping fit a real classic CAN bus at this cycle rate?"""

from __future__ import annotations

from hilrig.busload import BUS_LOAD_DESCRIPTION, BUS_LOAD_HELP, configure_bus_load_parser, run_bus_load
from hilrig.cli.common import Command

COMMANDS = (
    Command(
        name="bus-load",
        help=BUS_LOAD_HELP,
        description=BUS_LOAD_DESCRIPTION,
        configure=configure_bus_load_parser,
        run=run_bus_load,
    ),
)
