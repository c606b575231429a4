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
import shlex
import shutil
import subprocess
import sys
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from hilrig import resources
from hilrig.errors import BusUnavailableError, RigError

PATHS = ("native", "vm", "uml")
"""What `choose_path` answers and `BusOptions.mode` forces (besides "auto")."""

INSTALL_HINT = (
    "a kernel with vcan (modprobe vcan), or user-mode Linux (Debian: apt-get install "
    "user-mode-linux), or the micro-VM (Debian: apt-get install qemu-system-x86 linux-image-amd64 "
    "busybox-static; pip install virtme-ng)"
)
"""What to install when no path works, said once for `--help` and the errors."""

PASSED_VARIABLES = (
    "HOME", "LANG", "LC_ALL", "TERM", "CI", "PYTHONPATH", "PYTEST_ADDOPTS", "VIRTUAL_ENV",
    "NO_COLOR", "FORCE_COLOR", "COLUMNS", "XDG_CACHE_HOME",
)  # fmt: skip
"""Variables a guest's command gets from this process (with PATH and every HIL_* one)."""

GUEST_PRIVATE = ("/run", "/dev/shm", "/proc", "/sys")
"""Folders a guest has its own of: a path under one of them is not the host's inside."""


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


Say = Callable[[str], None]


def sayer(options: BusOptions) -> Say:
    def say(text: str) -> None:
        if not options.quiet:
            print(f"{options.prog}: {text}", file=sys.stderr, flush=True)

    return say


def tools_folders() -> list[Path]:
    """Where the helpers of the guests are looked for before PATH: the running Python
    environment's bin (the checkout's .venv/bin: virtme-ng, virtiofsd, linux.uml)."""
    return [Path(sys.prefix) / "bin", Path(sys.executable).parent]


def find_tool(name: str) -> Path | None:
    for folder in tools_folders():
        candidate = folder / name
        if candidate.is_file() and os.access(candidate, os.X_OK):
            return candidate
    found = shutil.which(name)
    return Path(found) if found else None


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
    from hilrig.session import guests

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


def record_path(text: str) -> None:
    """The path taken, into $HIL_BUS_PATH_FILE when set (test summaries read it)."""
    target = os.environ.get("HIL_BUS_PATH_FILE")
    if target:
        Path(target).parent.mkdir(parents=True, exist_ok=True)
        Path(target).write_text(text + "\n")


def named_paths(command: Sequence[str], cwd: Path) -> list[Path]:
    """The existing paths the command's words name: a word, or the value of `--opt=VALUE`,
    relative to `cwd`; each as spelled (absolute) and as resolved (a link into /tmp)."""
    found: list[Path] = []
    for word in command:
        for text in {word, word.partition("=")[2]}:
            if not text or "\0" in text or not ("/" in text or text in (".", "..")):
                continue
            path = Path(os.path.abspath(cwd / text))
            try:
                if not path.exists():
                    continue
                found += [path, path.resolve()]
            except OSError:
                continue
    return found


def visible_folders(command: Sequence[str], cwd: Path, extra: Iterable[Path] = ()) -> list[Path]:
    """The host folders a guest must show as they are here: the working folder, the running
    Python environment, the folders of the paths the command names, `extra`. BusUnavailableError
    names a path under a folder the guest has its own of (GUEST_PRIVATE), which cannot be."""
    wanted = [cwd, Path(sys.prefix), *extra, *named_paths(command, cwd)]
    for path in wanted:
        for private in GUEST_PRIVATE:
            if path.is_relative_to(private) and path != Path(private):
                raise BusUnavailableError(
                    f"{path} cannot be seen inside the bus's guest (its {private} is its own): "
                    "move it under your home folder or /tmp"
                )
    return sorted(set(wanted))


def tmp_binds(folders: Iterable[Path]) -> list[Path] | None:
    """The top folders under /tmp (a guest's /tmp is empty) that must be the host's inside: one
    per /tmp/<name> any of `folders` lies in, so that a venv's bin and its lib come together.
    None: /tmp itself is wanted (the guest keeps the host's /tmp)."""
    tops: set[Path] = set()
    for folder in folders:
        if folder == Path("/tmp"):
            return None
        if folder.is_relative_to("/tmp"):
            tops.add(Path("/tmp") / folder.relative_to("/tmp").parts[0])
    return sorted(tops)


def passed_environment() -> dict[str, str]:
    """The variables a guest's command gets: PASSED_VARIABLES, PATH and every HIL_* set here."""
    names = [*PASSED_VARIABLES, "PATH", *(n for n in os.environ if n.startswith("HIL_"))]
    return {name: os.environ[name] for name in names if os.environ.get(name)}


def command_lines(command: Sequence[str], cwd: Path, bus_path: str) -> list[str]:
    """The shell lines of a guest's script that enter this process's folder and environment and
    run the command (set +e: the script goes on to report its exit code)."""
    environment = passed_environment() | {resources.BUS_PATH_VARIABLE: bus_path}
    lines = [f"cd {shlex.quote(str(cwd))}"]
    lines += [f"export {name}={shlex.quote(value)}" for name, value in environment.items()]
    return [*lines, "set +e", shlex.join(command)]


def script_folder() -> Path:
    """Where a guest's script and its exit code are written: the checkout's build/with-vcan, else
    the user's cache ($XDG_CACHE_HOME/hilrig/bus), else the temporary folder."""
    if resources.CHECKOUT is not None:
        candidates = [resources.CHECKOUT / "build" / "with-vcan"]
    else:
        base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
        candidates = [Path(base) / "hilrig" / "bus"]
    candidates.append(Path(os.environ.get("TMPDIR") or "/tmp") / f"hilrig-bus-{os.getuid()}")
    for folder in candidates:
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError:
            continue
        if os.access(folder, os.W_OK):
            return folder
    raise BusUnavailableError(
        f"no writable folder for the guest's script: tried {', '.join(map(str, candidates))}"
    )


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
    from hilrig.session import guests

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
