"""`hilrig convert IN OUT`: a bus log from one format into another, frames and times kept.

Both formats follow the extensions (`hilrig.session.logformats`): candump `.log`, Vector `.asc`
and `.blf`, ASAM `.mf4`, `.csv`, `.trc`; IN may also be what else python-can reads. Times stay
UTC and exact to the coarser format's resolution (microseconds for .log and .asc). OUT appears
only whole.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from hilrig.cli.common import Command, UsageError, progress
from hilrig.cli.files import ArgKind, kind, output_file
from hilrig.cli.record import existing_log
from hilrig.session.logformats import BLF_CLOCKS, DEFAULT_BLF_CLOCK, FORMAT_NAMES, LOG_FORMATS

converted_path = output_file("log", suffixes=LOG_FORMATS)


@kind(ArgKind("input file", suffixes=LOG_FORMATS))
def convertible_log(text: str) -> Path:
    """IN: a readable log (`existing_log`) whose extension some reader takes, refused here
    rather than after OUT is parsed (python-can is imported only for an extension not ours)."""
    path = existing_log(text)
    suffixes = [suffix.lower() for suffix in path.suffixes]
    extension = suffixes[-2] if suffixes[-1:] == [".gz"] and len(suffixes) >= 2 else path.suffix.lower()
    if extension not in LOG_FORMATS:
        from hilrig.session.buslog import reader_suffixes

        readers = reader_suffixes()
        if extension not in readers:
            known = ", ".join(sorted({*LOG_FORMATS, *readers}))
            raise argparse.ArgumentTypeError(
                f"log {text}: no reader for {extension or 'no extension'} ({known})"
            )
    return path


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("input", type=convertible_log, metavar="IN", help="the log to read")
    parser.add_argument(
        "output", type=converted_path, metavar="OUT", help=f"the log to write: {', '.join(LOG_FORMATS)}"
    )
    for side, which in (("from", "IN"), ("to", "OUT")):
        parser.add_argument(
            f"--{side}-blf-clock",
            choices=BLF_CLOCKS,
            default=DEFAULT_BLF_CLOCK,
            help=f"a .blf {which}'s header start time: local time as CANoe/CANalyzer have it "
            "(default), or utc as python-can's own BLFWriter and BLFReader have it",
        )


def run(args: argparse.Namespace) -> int:
    from hilrig.session.buslog import read_log, whole_file_logger

    if args.input.resolve() == args.output.resolve():
        raise UsageError(f"{args.input} is both IN and OUT: name another OUT")
    frames = 0
    with (
        read_log(args.input, blf_clock=args.from_blf_clock) as logged,
        whole_file_logger(args.output, blf_clock=args.to_blf_clock) as logger,
    ):
        for message in logged:
            logger(message)
            frames += 1
    if frames == 0:
        args.output.unlink(missing_ok=True)
        raise UsageError(f"{args.input} holds no frames")
    kind = FORMAT_NAMES.get(args.output.suffix.lower(), args.output.suffix)
    progress(f"convert: {frames} frames {args.input} -> {args.output} ({kind})")
    return 0


COMMANDS = (
    Command(
        name="convert",
        help="convert a bus log between candump .log, Vector .asc/.blf and ASAM .mf4 (and .csv, .trc)",
        description=__doc__.split("\n", 1)[1].strip() + "\n\n"
        "  hilrig convert out/scenarios/test_x/bus.log bus.blf      # for CANoe / CANalyzer\n"
        "  hilrig convert bus.log bus.mf4                           # for CANape, asammdf\n"
        "  hilrig convert logger.mf4 logger.log                     # a data logger's MF4\n"
        "  hilrig convert old.blf old.asc --from-blf-clock utc      # a BLF python-can wrote",
        configure=configure,
        run=run,
    ),
)
