"""`hilrig`: the rig's command-line tool, for people at a bench and for `make run`.

    hilrig fields --kind parameter            # the table, no bus needed
    hilrig dbc --node-id 0x20 -o board-32.dbc # the DBC for a board at another node id
    hilrig get motor_velocity velocity_kp     # SDO, values with units
    hilrig set velocity_kp=0.2                # SDO; a refusal is explained in words
    hilrig sdo read 0x1018:1                  # any object by index, value and hex
    hilrig nmt start --wait                   # NMT, and the state the heartbeat then shows
    hilrig watch --sync-period-ms 10          # live table of the TPDO fields
    hilrig monitor                            # every frame live, decoded with the board's names
    hilrig capture motor_velocity --samples 2000   # the board's recorder: every cycle, uploaded
    hilrig scan                               # which nodes are on the bus
    hilrig lss number --chain                 # new boards: node ids over LSS, stored
    hilrig params save board.dcf              # the stored parameters as a DCF (load: the reverse)
    hilrig flash build/release/images/joint-firmware.img   # program download (CiA 302-3), restart, version
    hilrig record bus.log / replay bus.log --decode
    hilrig diff good/trace.rrd out/demo/trace.rrd   # the first cycle the runs differ
    hilrig bus-load --bitrate 500k            # will the PDO exchange fit a real bus?
    hilrig sim --out out/demo                 # firmware + physics in lockstep, a summary
    hilrig soak --cycles 1000000              # the long run: no cycle lost, memory flat
    hilrig new-board fan                      # a new board's project: table, firmware, plant, scenario

Every command takes `--help`; those on a bus take python-can's bus options (`-i`, `-c`, `-b`,
`--fd`, `--data-bitrate`, `--bus-kwargs`), defaulting to python-can's configuration.
The exit codes are in `EXIT_CODES` (printed by `hilrig --help`).

Adding a command: write `hilrig/cli/<module>.py` with `COMMANDS = (Command(...),)` and add
the module's name to `COMMAND_MODULES`.
"""

# ruff: noqa: E402 (the imports after the first two run under the start-up SIGINT handler)
from __future__ import annotations

import signal
import sys


def _interrupted_at_start(signum: int, frame: object) -> None:
    """Ctrl-C while the command's libraries are still imported: one line and 130, no traceback
    (nothing has been opened or written yet). Python's own handler is back once they are."""
    sys.stderr.write("hilrig: interrupted\n")
    raise SystemExit(130)


try:
    _PREVIOUS_SIGINT = signal.signal(signal.SIGINT, _interrupted_at_start)
    _AT_START = True
except ValueError:  # imported from another thread than the main one: leave SIGINT alone
    _AT_START = False

import argparse
import importlib
import importlib.metadata
import logging
import os
import textwrap
import traceback
from collections.abc import Sequence
from types import FrameType
from typing import NoReturn

from boardproto import TableError
from hilrig import resources
from hilrig.cli.common import Command, UsageError, add_verbose_option, choose_table, one_line
from hilrig.errors import LogFormatError, RigError
from hilrig.session.run import RunOptionError

if _AT_START:  # imported: a program that imports hilrig.cli keeps its own handler
    signal.signal(signal.SIGINT, _PREVIOUS_SIGINT or signal.default_int_handler)

COMMAND_MODULES: tuple[str, ...] = (
    "fields",
    "dbc",
    "sdo",
    "sdo_raw",
    "nmt",
    "watch",
    "monitor",
    "capture",
    "scan",
    "lss",
    "params",
    "flash",
    "record",
    "convert",
    "sim",
    "view",
    "diff",
    "busload",
    "busstat",
    "pdo",
    "soak",
    "new_board",
    "bus",
    "completion",
)
"""Modules of `hilrig.cli` whose COMMANDS are registered, in the order `--help` lists them."""

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130

EXIT_CODES = """\
exit codes (every error is one line on stderr; a traceback is a bug in hilrig):
  0    done; a warning (e.g. bus load above 70 %) is still done
  1    it ran and failed: the bus or adapter would not open or went away, the node was
       silent or refused (the SDO abort code in words), a wait timed out, the bus load is
       above 100 %, a log file's content cannot be parsed (at its start or part-way)
  2    refused before anything ran, nothing sent: the command line is wrong (an option,
       value, name or index), or something it needs is missing or unusable: a file that does
       not exist or whose format is not read, the table, EDS or DBC, python-can's
       configuration, an interface this machine cannot use or whose package is not
       installed (the line says what to install); fix that, then run it again.
       Also: the node is not the table's board (a command that writes reads its 0x1018
       vendor id and product code first, and they differ), nothing written; --force writes
  130  interrupted (Ctrl-C, SIGTERM), at any moment, start-up included; files written so far
       are whole"""

TABLE_CHOICE = textwrap.fill(
    "the table (its fields, EDS and DBC, and the identity a write is checked against): --table, "
    f"else {resources.TABLE_ORDER}; a table other than the default is named in a line on stderr",
    width=95,
)


def version() -> str:
    """'hilrig 0.1.0 (python-can 4.6.1, canopen 2.4.1, cantools 45.1.0, Python 3.11.7)': what a
    bug report needs. From the installed package's metadata; run from a checkout that is not
    installed, from rig/pyproject.toml."""
    try:
        own = importlib.metadata.version("hilrig")
    except importlib.metadata.PackageNotFoundError:
        own = resources.checkout_version()
    parts = []
    for name in ("python-can", "canopen", "cantools"):
        try:
            parts.append(f"{name} {importlib.metadata.version(name)}")
        except importlib.metadata.PackageNotFoundError:
            parts.append(f"{name} not installed")
    python = ".".join(str(part) for part in sys.version_info[:3])
    return f"hilrig {own} ({', '.join(parts)}, Python {python})"


class _VersionAction(argparse.Action):
    """--version, looked up only when asked for (metadata look-ups cost time in the micro-VM)."""

    def __init__(self, option_strings: Sequence[str], dest: str, help: str | None = None) -> None:
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, help=help)

    def __call__(self, parser: argparse.ArgumentParser, *_: object) -> NoReturn:
        print(version())
        parser.exit(EXIT_OK)


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
        epilog="`hilrig COMMAND --help` describes each command, with examples.\n\n"
        + EXIT_CODES
        + "\n\n"
        + TABLE_CHOICE,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_verbose_option(parser)
    parser.set_defaults(verbose=False)
    parser.add_argument(
        "--version", action=_VersionAction, help="print the versions of hilrig and its libraries"
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True, parser_class=Parser)
    for command in commands():
        command_parser = sub.add_parser(
            command.name,
            help=command.help,
            description=command.description,
            epilog="exit codes: 0 done, 1 failed (bus, node, data), 2 bad command line; "
            "`hilrig --help` has the whole rule",
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )
        add_verbose_option(command_parser)
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
    try:
        parser = build_parser(argv)  # imports the command modules
        args = parser.parse_args(argv)
    except SystemExit as exit_:  # --help (0) or a bad command line (2)
        return exit_.code if isinstance(exit_.code, int) else EXIT_USAGE
    except KeyboardInterrupt:
        print("hilrig: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    prog: str = args.parser.prog
    _configure_logging(args.verbose)
    previous = signal.getsignal(signal.SIGTERM)
    try:
        signal.signal(signal.SIGTERM, _terminate)
    except ValueError:  # not the main thread: leave SIGTERM alone
        previous = None
    try:
        choose_table(args)
        return int(args.run(args))
    except (UsageError, TableError, LogFormatError, RunOptionError) as error:  # a bad argument
        return _report(prog, error, EXIT_USAGE, verbose=args.verbose)
    except BrokenPipeError:  # `hilrig ... | head` stopped reading: not an error
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_OK
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except (RigError, OSError) as error:
        return _report(prog, error, EXIT_FAILED, verbose=args.verbose)
    except Exception as error:
        # What python-can, canopen and cantools raise is about the bus, the node or a file;
        # anything else is a bug in hilrig: its traceback is what a report needs.
        if type(error).__module__.split(".")[0] not in ("can", "canopen", "cantools"):
            raise
        return _report(prog, error, EXIT_FAILED, verbose=args.verbose)
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def _report(prog: str, error: BaseException, code: int, *, verbose: bool) -> int:
    """One line on stderr; with --verbose the traceback first (which call failed, and why)."""
    if verbose:
        traceback.print_exception(error, file=sys.stderr)
    print(f"{prog}: error: {one_line(error)}", file=sys.stderr)
    return code
