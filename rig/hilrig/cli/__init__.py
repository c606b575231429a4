"""`hilrig`: the rig's command-line tool, for people at a bench and for `make run`.

    hilrig fields --kind parameter            # the table, no bus needed
    hilrig dbc --node-id 0x20 -o board-32.dbc # the DBC for a board at another node id
    hilrig get motor_velocity velocity_kp     # SDO, values with units
    hilrig set velocity_kp=0.2                # SDO; a refusal is explained in words
    hilrig watch --sync-period-ms 10          # live table of the TPDO fields
    hilrig capture motor_velocity --samples 2000   # the board's recorder: every cycle, uploaded
    hilrig scan                               # which nodes are on the bus
    hilrig record bus.log / replay bus.log --decode
    hilrig sim --out out/demo                 # firmware + physics in lockstep, a summary
    hilrig soak --cycles 1000000              # the long run: no cycle lost, memory flat

Every command takes `--interface`/`--channel` (any python-can interface) and `--help`.
Exit codes: 0 done, 1 the bus or the node failed (one line on stderr, no traceback),
2 the command line is wrong (one line saying what to type instead), 130 interrupted.

Adding a command: write `hilrig/cli/<module>.py` with `COMMANDS = (Command(...),)` and add
the module's name to `COMMAND_MODULES`.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import signal
import sys
from collections.abc import Sequence
from types import FrameType
from typing import NoReturn

from boardproto import TableError
from hilrig.cli.common import Command, UsageError, one_line
from hilrig.errors import RigError

COMMAND_MODULES: tuple[str, ...] = (
    "fields",
    "dbc",
    "sdo",
    "watch",
    "capture",
    "scan",
    "record",
    "sim",
    "busload",
    "soak",
)
"""Modules of `hilrig.cli` whose COMMANDS are registered, in the order `--help` lists them."""

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130


class Parser(argparse.ArgumentParser):
    """argparse with a one-line error that points at the command's --help."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see `{self.prog} --help`)\n")


def commands() -> list[Command]:
    found: list[Command] = []
    for module_name in COMMAND_MODULES:
        module = importlib.import_module(f"hilrig.cli.{module_name}")
        found.extend(module.COMMANDS)
    return found


def build_parser(argv: Sequence[str] | None = None) -> Parser:
    """The whole parser; given the command line, only the command it names is configured (its
    options can import what the other commands never need: a call starts faster, which counts
    most where Python is slow, in the micro-VM and on small boards' hosts)."""
    selected = next((a for a in argv if not a.startswith("-")), None) if argv is not None else None
    parser = Parser(
        prog="hilrig",
        description=__doc__.split("\n\n")[0],
        epilog="`hilrig COMMAND --help` describes each command.",
    )
    parser.add_argument(
        "-v", "--verbose", action="store_true", help="log what python-can and canopen do (to stderr)"
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True, parser_class=Parser)
    for command in commands():
        command_parser = sub.add_parser(
            command.name,
            help=command.help,
            description=command.description,
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )
        # Without a command line (tests, docs) every command is configured; with one, only
        # the command it names (none for `hilrig --help`, which lists names and help only).
        if argv is None or command.name == selected:
            command.configure(command_parser)
        command_parser.set_defaults(run=command.run, parser=command_parser)
    return parser


def _configure_logging(verbose: bool) -> None:
    """canopen logs each SDO failure it also raises; the error line says it once, in words."""
    for name in ("can", "canopen"):
        logging.getLogger(name).setLevel(logging.DEBUG if verbose else logging.CRITICAL)
    if verbose:
        logging.basicConfig(level=logging.DEBUG, format="%(name)s: %(message)s")


def _terminate(signum: int, frame: FrameType | None) -> None:
    raise KeyboardInterrupt  # SIGTERM ends a command like Ctrl-C: files closed, whole


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command; returns the exit code (the console script exits with it)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(argv)
    try:
        args = parser.parse_args(argv)
    except SystemExit as exit_:  # --help (0) or a bad command line (2)
        return exit_.code if isinstance(exit_.code, int) else EXIT_USAGE
    prog: str = args.parser.prog
    _configure_logging(args.verbose)
    previous = signal.getsignal(signal.SIGTERM)
    try:
        signal.signal(signal.SIGTERM, _terminate)
    except ValueError:  # not the main thread: leave SIGTERM alone
        previous = None
    try:
        return int(args.run(args))
    except (UsageError, TableError) as error:  # a bad table file is a bad argument (--table)
        print(f"{prog}: error: {one_line(error)}", file=sys.stderr)
        return EXIT_USAGE
    except BrokenPipeError:  # `hilrig ... | head` stopped reading: not an error
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_OK
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except (RigError, OSError) as error:
        print(f"{prog}: error: {one_line(error)}", file=sys.stderr)
        return EXIT_FAILED
    except Exception as error:
        if type(error).__module__.split(".")[0] not in ("can", "canopen", "cantools"):
            raise
        print(f"{prog}: error: {one_line(error)}", file=sys.stderr)
        return EXIT_FAILED
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
