"""`hilrig bus -- CMD [ARGS]`: a command with a real SocketCAN vcan0, whatever the kernel
(`hilrig.session.vcan`; the checkout's tools/with-vcan is this command)."""

from __future__ import annotations

import argparse
import os
import sys

from hilrig.cli.common import Command, UsageError
from hilrig.cli.files import existing_file
from hilrig.session import vcan

DESCRIPTION = f"""\
Run COMMAND with a real SocketCAN bus vcan0, from any folder. The first path that works here:

  native    the kernel has vcan (or vcan0 exists): vcan0 made, COMMAND run here
  vm (KVM)  a qemu micro-VM with a stock Debian kernel (virtme-ng), when a short probe boot
            proves KVM works here (once per boot of the machine)
  uml       user-mode Linux: a Linux kernel as a process, this machine's files; one core, the
            host's speed; no AddressSanitizer build can start in it (--no-uml for those)
  vm        the micro-VM under software emulation: about 20 times slower

It says which it took (on stderr; --which: only that). In a guest COMMAND runs in this folder
with PATH, HOME, every HIL_* variable and a few more; visible there as here: this folder, the
Python environment of this hilrig and every existing path COMMAND names (those under /tmp too,
whose guest /tmp is its own), or an error names what cannot be. $HIL_BUS_PATH inside says the
path; it never picks a firmware: a project's pytest.ini (hil_firmware) and $HIL_FIRMWARE do, and
the pytest plugin names the firmware it started in its header. The exit code is COMMAND's
(127: not found); Ctrl-C stops the guest: one line, exit 130.

None works? Install {vcan.INSTALL_HINT}.

environment: HIL_UML_KERNEL (a linux.uml; default: the one beside this Python, else on PATH),
HIL_VM_KERNEL (a vmlinuz), HIL_VM_MEMORY (default 4G), HIL_VM_CPUS (default: all cores),
HIL_VM_CPU, HIL_VM_KERNEL_ARGS (software emulation), HIL_BUS_PATH_FILE (gets the path taken)

examples:
  hilrig bus -- python -m pytest -q                 # a project's scenarios
  hilrig bus --uml -- candump vcan0                 # force user-mode Linux
  hilrig bus --which                                # which path, nothing run"""

KERNEL_VARIABLES = {"uml": "HIL_UML_KERNEL", "vm": "HIL_VM_KERNEL"}
"""Where --kernel goes: the variable hilrig.session.guests reads for that path."""
EXIT_NOT_FOUND = 127
EXIT_INTERRUPTED = 130


def configure(parser: argparse.ArgumentParser) -> None:
    path = parser.add_mutually_exclusive_group()
    path.add_argument("--native", dest="mode", action="store_const", const="native",
                      help="the kernel's own vcan; fail if it has none")  # fmt: skip
    path.add_argument("--vm", dest="mode", action="store_const", const="vm",
                      help="always the qemu micro-VM (to reproduce CI on a host with vcan)")  # fmt: skip
    path.add_argument("--uml", dest="mode", action="store_const", const="uml",
                      help="always user-mode Linux (Debian: apt-get install user-mode-linux)")  # fmt: skip
    kvm = parser.add_mutually_exclusive_group()
    kvm.add_argument("--kvm", dest="kvm", action="store_const", const="yes", help="KVM in the VM, no probe")
    kvm.add_argument("--no-kvm", dest="kvm", action="store_const", const="no", help="never KVM")
    parser.add_argument("--no-uml", dest="uml", action="store_false",
                        help="never user-mode Linux (a command that runs ASan builds)")  # fmt: skip
    parser.add_argument(
        "--kernel",
        type=existing_file("kernel", "give a linux.uml with --uml or a vmlinuz with --vm"),
        metavar="FILE",
        help="the guest's kernel: a linux.uml with --uml ($HIL_UML_KERNEL), a vmlinuz with --vm "
        "($HIL_VM_KERNEL)",
    )
    parser.add_argument("--quiet", action="store_true", help="nothing of our own unless something fails")
    parser.add_argument(
        "--which", action="store_true", help="print the path these options take here; run nothing"
    )
    parser.add_argument("command", nargs=argparse.REMAINDER, metavar="-- COMMAND [ARGS...]",
                        help="what to run with the bus")  # fmt: skip
    parser.set_defaults(mode="auto", kvm="auto")


def options(args: argparse.Namespace) -> vcan.BusOptions:
    return vcan.BusOptions(
        mode=args.mode, kvm=args.kvm, uml=args.uml, quiet=args.quiet, prog=args.parser.prog
    )


def run(args: argparse.Namespace) -> int:
    command = list(args.command)
    if command[:1] == ["--"]:
        command = command[1:]
    chosen = options(args)
    if args.kernel is not None:
        if args.mode not in KERNEL_VARIABLES:
            raise UsageError("--kernel needs --uml (a linux.uml) or --vm (a vmlinuz)")
        os.environ[KERNEL_VARIABLES[args.mode]] = str(args.kernel.resolve())
    if args.which:
        print(vcan.choose_path(chosen, vcan.sayer(chosen)))
        return 0
    if not command:
        raise UsageError("no command given: hilrig bus [OPTIONS] -- COMMAND [ARGS...]")
    try:
        return vcan.run(command, chosen)
    except vcan.CommandNotFoundError as error:
        print(f"{chosen.prog}: error: {error}", file=sys.stderr)
        return EXIT_NOT_FOUND
    except KeyboardInterrupt:  # the guest and its command already stopped (hilrig.session.guests)
        print(f"{chosen.prog}: interrupted, the bus and its command stopped", file=sys.stderr)
        return EXIT_INTERRUPTED


COMMANDS = (
    Command(
        name="bus",
        help="run a command with a vcan bus: natively, in user-mode Linux or in a micro-VM",
        description=DESCRIPTION,
        configure=configure,
        run=run,
    ),
)
