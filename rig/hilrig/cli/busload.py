"""`hilrig bus-load`: will this PDO mapping fit a real classic CAN bus at this cycle rate?"""

from __future__ import annotations

from hilrig.busload import BUS_LOAD_DESCRIPTION, BUS_LOAD_HELP, configure_bus_load_parser, run_bus_load
from hilrig.cli.common import Command

COMMANDS = (
    Command(
        name="bus-load",
        help=BUS_LOAD_HELP,
        description=BUS_LOAD_DESCRIPTION
        + "\n\n  hilrig bus-load                                # the default mapping, 1 kHz, all bit rates"
        "\n  hilrig bus-load --rate-hz 200 --bitrate 500k   # will it fit a 500 kbit/s bus at 200 Hz?"
        "\n  hilrig bus-load --table my_board.toml          # another board's table",
        configure=configure_bus_load_parser,
        run=run_bus_load,
    ),
)
