"""Command line: `python -m boardproto generate --table board.toml --out-dir build/protocol`,
`python -m boardproto standard` (the blocks every table gets)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from boardproto.cia301_header import generate_cia301_header
from boardproto.cia302_header import generate_cia302_header
from boardproto.cia305_header import generate_cia305_header
from boardproto.cia402_header import generate_cia402_header
from boardproto.cpp_header import generate_header
from boardproto.dbc import generate_dbc
from boardproto.eds import generate_eds
from boardproto.image import ImageBuildError, build_image, write_image
from boardproto.loader import TableError, load_table
from boardproto.outputs import write_if_changed
from boardproto.standard import STANDARD_TABLE
from boardproto.table import BoardTable
from boardproto.vectors import generate_field_vectors

EXIT_BAD_INPUT = 2

# Output path (relative to --out-dir) -> generator.
OUTPUTS: dict[str, Callable[[BoardTable], str]] = {
    "include/board/fields.hpp": generate_header,
    "include/board/cia301.hpp": lambda _table: generate_cia301_header(),
    "include/board/cia302.hpp": lambda _table: generate_cia302_header(),
    "include/board/cia305.hpp": lambda _table: generate_cia305_header(),
    "include/board/cia402.hpp": lambda _table: generate_cia402_header(),
    "board.eds": generate_eds,
    "board.dbc": generate_dbc,
    "field_vectors.csv": generate_field_vectors,
}


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m boardproto",
        description="Generate the board's C++ headers, CANopen EDS, DBC and field vectors "
        "from the field table (protocol/board.toml) and the CiA 301 rules (boardproto.cia301).",
    )
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    generate = commands.add_parser(
        "generate",
        help="validate the table and write the generated files",
        description="Validate the table and write, under OUT_DIR: "
        + ", ".join(OUTPUTS)
        + ". Files whose content is unchanged are not touched. On a bad table, "
        "prints one error line and exits with status 2.",
    )
    generate.add_argument(
        "--table", type=Path, required=True, help="the field table, e.g. protocol/board.toml"
    )
    generate.add_argument("--out-dir", type=Path, required=True, help="output directory, e.g. build/protocol")
    generate.add_argument("--quiet", action="store_true", help="do not list the files that were rewritten")
    commands.add_parser(
        "standard",
        help="print the standard blocks every table gets unless it overrides them",
        description="Print, in board.toml's format, the [node] communication parameters, the "
        "[[emcy]] codes, the [recorder] and its [[enum]]s a table gets without writing them "
        "(boardproto.standard says how a table overrides them).",
    )
    image = commands.add_parser(
        "image",
        help="wrap a built firmware executable into a program download image (CiA 302-3)",
        description="Write OUT: the image header of boardproto.cia302 (the table's product code, "
        "the executable's 0x100A version, payload length and CRC-32), then the executable.",
    )
    image.add_argument("--table", type=Path, required=True, help="the field table, e.g. protocol/board.toml")
    image.add_argument(
        "--firmware", type=Path, required=True, help="the executable, e.g. build/bin/joint-firmware"
    )
    image.add_argument("--out", type=Path, required=True, help="the image file to write")
    image.add_argument(
        "--version-suffix",
        default="",
        help="stamp the executable's version plus this suffix into the copy (a second image of one build)",
    )
    image.add_argument("--strip", action="store_true", help="strip symbols and debug information first")
    image.add_argument("--quiet", action="store_true", help="do not say what was written")
    return parser


def generate(table_path: Path, out_dir: Path) -> list[Path]:
    """Generate every output; returns the files that were (re)written."""
    table = load_table(table_path)
    texts = {out_dir / relative: make(table) for relative, make in OUTPUTS.items()}
    return [path for path, text in texts.items() if write_if_changed(path, text)]


def main(argv: Sequence[str] | None = None) -> int:
    arguments = _parser().parse_args(argv)
    if arguments.command == "standard":
        print(STANDARD_TABLE, end="")
        return 0
    if arguments.command == "image":
        try:
            table = load_table(arguments.table)
            image = build_image(
                table, arguments.firmware, version_suffix=arguments.version_suffix, strip=arguments.strip
            )
        except (TableError, ImageBuildError, OSError) as error:
            print(f"boardproto: error: {error}", file=sys.stderr)
            return EXIT_BAD_INPUT
        write_image(arguments.out, image)
        if not arguments.quiet:
            print(f"boardproto: wrote {arguments.out} ({len(image)} bytes)")
        return 0
    try:
        written = generate(arguments.table, arguments.out_dir)
    except TableError as error:
        print(f"boardproto: error: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if not arguments.quiet:
        for path in written:
            print(f"boardproto: wrote {path}")
    return 0
