"""A command with a real SocketCAN `vcan0`, whatever the kernel: `hilrig bus -- CMD` and the
checkout's `tools/with-vcan` are this module.

Four paths, the first that works here (`choose_path`):

1. native: the kernel has vcan (or `vcan0` already exists): `vcan0` made and brought up, the
   command run here;
2. a qemu micro-VM under KVM (virtme-ng with a stock Debian kernel that ships vcan), when a
   short probe boot proves KVM works on this machine;
3. user-mode Linux (Debian's `user-mode-linux` kernel as a process, this machine's root file
   system through hostfs): processes at the host's speed, one core a kernel;
4. the qemu micro-VM under software emulation: every instruction emulated, about 20 times slower.

In a guest the command runs with this process's working folder and the variables a run needs
(`passed_environment`); the folders it works in are visible there (`visible_folders`: the working
folder, the running Python environment, every existing path the command names, those under /tmp
included, whose guest /tmp is its own), or a one-line error names the one that cannot be. Its exit
code comes back out; nothing is left running, Ctrl-C included (KeyboardInterrupt after the guest
is stopped). Inside, `$HIL_BUS_PATH` says which path was taken ("native", "vm:<kernel>",
"uml:<kernel>"); it never chooses a firmware (the caller's configuration does; the checkout's
defaults read `$HIL_BUS_PATH`, `hilrig.resources`).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from hilrig import resources
from hilrig.errors import BusUnavailableError, RigError
from hilrig.session import guests
from hilrig.session.guests import (
    GUEST_PRIVATE,
    INSTALL_HINT,
    Say,
    command_lines,
    find_tool,
    passed_environment,
    record_path,
    script_folder,
    tmp_binds,
    visible_folders,
)

PATHS = ("native", "vm", "uml")
"""What `choose_path` answers and `BusOptions.mode` forces (besides "auto")."""


class CommandNotFoundError(RigError, FileNotFoundError):
    """The command to run is not an executable here (exit code 127, as a shell's)."""


@dataclass(frozen=True)
class BusOptions:
    """How `run` finds a bus. mode: "auto" or one of PATHS; kvm: "auto" (probe once), "yes"
    (no probe), "no"; uml: False never takes user-mode Linux (a command that runs ASan builds)."""

    mode: str = "auto"
    kvm: str = "auto"
    uml: bool = True
    quiet: bool = False
    prog: str = "hilrig bus"


def sayer(options: BusOptions) -> Say:
    def say(text: str) -> None:
        if not options.quiet:
            print(f"{options.prog}: {text}", file=sys.stderr, flush=True)

    return say


def native_vcan_available() -> bool:
    if _run_quiet(["ip", "link", "show", "vcan0"]):
        return True
    return os.geteuid() == 0 and _run_quiet(["modprobe", "vcan"])


def _run_quiet(argv: Sequence[str], timeout: float | None = None) -> bool:
    try:
        done = subprocess.run(
            argv, stdin=subprocess.DEVNULL, capture_output=True, timeout=timeout, check=False
        )
    except (OSError, subprocess.TimeoutExpired):
        return False
    return done.returncode == 0


def choose_path(options: BusOptions, say: Say) -> str:
    """Which of PATHS `options` take here (see the module docstring)."""
    if options.mode != "auto":
        return options.mode
    if native_vcan_available():
        return "native"
    if not options.uml or options.kvm == "yes" or guests.find_uml_kernel() is None:
        return "vm"
    if options.kvm == "auto":
        kernel = guests.find_vm_kernel()
        if kernel is not None and find_tool("vng") is not None and guests.kvm_works(kernel, say):
            return "vm"
    return "uml"


def run_native(command: Sequence[str], say: Say) -> int:
    """vcan0 made and brought up, then the command in place of this process (its exit code,
    its signals: nothing of ours left between)."""
    if not _run_quiet(["ip", "link", "show", "vcan0"]):
        done = subprocess.run(["ip", "link", "add", "dev", "vcan0", "type", "vcan"], check=False)
        if done.returncode != 0:
            raise BusUnavailableError(
                "could not create vcan0 (`ip link add dev vcan0 type vcan` failed): run as root"
            )
    _run_quiet(["ip", "link", "set", "up", "vcan0"])
    release = os.uname().release
    say(f"bus path: native SocketCAN vcan0 (kernel {release})")
    record_path(f"native vcan0 (kernel {release})")
    environment = os.environ | {resources.BUS_PATH_VARIABLE: "native"}
    sys.stdout.flush()
    sys.stderr.flush()
    try:
        os.execvpe(command[0], list(command), environment)
    except FileNotFoundError:
        raise CommandNotFoundError(f"{command[0]}: command not found") from None


def run(command: Sequence[str], options: BusOptions) -> int:
    """Run `command` with a vcan0 (see the module docstring); its exit code."""
    say = sayer(options)
    if options.mode not in ("auto", *PATHS):
        raise ValueError(f"unknown bus path {options.mode!r}: one of auto, {', '.join(PATHS)}")
    _require_command(command)
    mode = choose_path(options, say)
    if mode == "native":
        if not native_vcan_available():
            raise BusUnavailableError("this kernel has no vcan (modprobe vcan failed): use --vm or --uml")
        return run_native(command, say)
    cwd = Path.cwd()
    folders = visible_folders(command, cwd, [script_folder()])
    if mode == "uml":
        return guests.run_uml(command, cwd, folders, say)
    return guests.run_vm(command, cwd, folders, options.kvm, say)


def _require_command(command: Sequence[str]) -> None:
    """CommandNotFoundError unless the command's first word runs here (and so, with this
    machine's own userland, inside)."""
    if not command:
        raise ValueError("no command given: hilrig bus [OPTIONS] -- COMMAND [ARGS...]")
    if shutil.which(command[0]) is None:
        hint = ""
        if command[0].startswith(("/tmp/", "./", "../")) or "/" in command[0]:
            hint = " (a path: does it exist and is it executable?)"
        raise CommandNotFoundError(f"{command[0]}: command not found{hint}")


__all__ = [
    "GUEST_PRIVATE",
    "INSTALL_HINT",
    "PATHS",
    "BusOptions",
    "CommandNotFoundError",
    "choose_path",
    "command_lines",
    "find_tool",
    "passed_environment",
    "run",
    "tmp_binds",
    "visible_folders",
]
