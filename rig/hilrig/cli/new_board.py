"""`hilrig new-board NAME`: a new board's project folder (hilrig.apps.scaffold), whose scenario
passes as generated once its firmware is built against hil-rig's firmware package."""

from __future__ import annotations

import argparse
from pathlib import Path

from hilrig.cli.common import Command, UsageError, node_id
from hilrig.cli.files import output_folder

DESCRIPTION = """\
Write a new board's project into a new folder (default: ./NAME): its table (board.toml, only
the board's own fields: the standard blocks come from the defaults), its firmware (components
and a main on hil-rig's board application, CMakeLists.txt against the installed firmware
package), its plant, pytest.ini, one scenario and a CI example. As generated it builds and its
scenario passes; then make the table, the components and the plant your board's.

examples:
  hilrig new-board fan                     # ./fan
  hilrig new-board fan --dir boards/fan --node-id 0x21
  cd fan && cmake -S . -B build -DCMAKE_PREFIX_PATH=PREFIX -DHILFW_PYTHON=$VIRTUAL_ENV/bin/python \\
    && cmake --build build && hilrig bus -- python -m pytest
(PREFIX: hil-rig's firmware package, installed by `make hilfw` in hil-rig.)"""


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("name", metavar="NAME", help="the board's name: lower case, digits and _ (e.g. fan)")
    parser.add_argument(
        "--dir",
        type=output_folder,
        default=None,
        help="the new folder (default: ./NAME); must not exist or be empty",
    )
    parser.add_argument(
        "--node-id", type=node_id, default=0x20, help="the board's default node id (default: 0x20)"
    )


def run(args: argparse.Namespace) -> int:
    from hilrig.apps.scaffold import ScaffoldError, new_board

    folder: Path = args.dir if args.dir is not None else Path(args.name)
    try:
        written = new_board(args.name, folder, node_id=args.node_id)
    except ScaffoldError as error:
        raise UsageError(str(error)) from None
    print(f"new-board: {args.name} in {folder}/ ({len(written)} files):")
    for path in written:
        print(f"  {path}")
    print("next: build its firmware (README.md in it), then `hilrig bus -- python -m pytest` there")
    return 0


COMMANDS = (
    Command(
        "new-board",
        "scaffold a new board's project (table, firmware, plant, scenario)",
        DESCRIPTION,
        configure,
        run,
    ),
)
