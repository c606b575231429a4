"""`hilrig flash FILE.img`: program download (CiA 302-3) of a firmware image into a board.

The image is checked here first (its header: a firmware image, for this table's product code,
its payload whole); a wrong one is refused with one line before anything is sent. So is a board
that is not the table's (its 0x1018 vendor id and product code; --force: flashed anyway). Then the
board's program is stopped (0x1F51), its staged image cleared, the image sent into 0x1F50 by
SDO block transfer (progress on stderr), and started: the board restarts from it and sends its
boot-up. The new 0x100A version and 0x1F56 software id are printed. The board checks the image
again itself; a refusal or Ctrl-C aborts the transfer and the board runs on with its old image.
`python -m boardproto image` (or `make build`: build/release/images/) makes images.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from boardproto.cia302 import IMAGE_HEADER_BYTES, FlashError, ImageError, ImageHeader, flash_error
from hilrig.cli.common import (
    Command,
    UsageError,
    add_node_options,
    board_node,
    describe_bus,
    load_table,
    open_bus,
    positive_float,
    progress,
    resolved_node_id,
)
from hilrig.cli.files import existing_file

IMAGE_SUFFIXES = (".img",)
IMAGE_HINT = (
    "`make build` writes build/release/images/joint-firmware.img; `python -m boardproto image` wraps a build"
)


def sniff_image(path: Path) -> str | None:
    """A firmware image starts with the header of boardproto.cia302."""
    with path.open("rb") as file:
        start = file.read(IMAGE_HEADER_BYTES)
    try:
        ImageHeader.unpack(start)
    except ImageError as error:
        return f"is not a firmware image: {error}"
    return None


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "file",
        type=existing_file("image", IMAGE_HINT, suffixes=IMAGE_SUFFIXES, sniff=sniff_image),
        metavar="FILE.img",
        help="the firmware image to download",
    )
    parser.add_argument(
        "--boot-timeout",
        type=positive_float,
        default=30.0,
        metavar="S",
        help="seconds to wait for the boot-up of the new image (default: 30)",
    )
    add_node_options(parser, sdo_timeout_s=5.0, writes=True)


def checked_image(path: Path, product_code: int) -> tuple[ImageHeader, bytes]:
    """The image's header and bytes; UsageError (one line, exit 2) when the board would refuse it."""
    image = path.read_bytes()
    try:
        header = ImageHeader.unpack(image)
        header.check_board(product_code)
        header.check_payload(image[IMAGE_HEADER_BYTES:])
    except ImageError as error:
        raise UsageError(f"image {path} refused: {error}") from None
    return header, image


def run(args: argparse.Namespace) -> int:
    from hilrig.wire.program import flash

    table = load_table(args)
    node_id = resolved_node_id(args, table)
    header, image = checked_image(args.file, table.board.node.product_code)

    def report(sent: int, total: int) -> None:
        progress(f"flash: {sent}/{total} bytes ({100 * sent // total} %)")

    with open_bus(args) as bus, board_node(args, bus, table, writes=True) as node:
        # Every segment sent is also on canopen's bus: without this, the boot-up of the new image
        # would queue behind all of them in its receive thread.
        node.receive_only_answers()
        progress(
            f"flash: {args.file} (version {header.software_version}, {len(image)} bytes) "
            f"into node 0x{node_id:02X} on {describe_bus(args)}"
        )
        result = flash(node, image, progress=report, boot_timeout_s=args.boot_timeout)
    error = flash_error(result.flash_status)
    status = "ok" if error == FlashError.NO_ERROR else f"0x{result.flash_status:08X} ({error})"
    print(
        f"node 0x{node_id:02X}: running version {result.software_version}, "
        f"software id 0x{result.software_id:08X} (image 0x{header.payload_crc32:08X}), flash status {status}"
    )
    return 0 if result.software_id == header.payload_crc32 else 1


COMMANDS = (
    Command(
        name="flash",
        help="download a firmware image into a board (CiA 302-3) and start it",
        description=__doc__.split("\n\n", 1)[1].strip() + "\n\n"
        "  hilrig flash build/release/images/joint-firmware.img           # the table's node (0x10)\n"
        "  hilrig flash build/release/images/joint-firmware.img -n 0x12   # another board\n",
        configure=configure,
        run=run,
    ),
)
