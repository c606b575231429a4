"""The two guests `hilrig.session.vcan` runs a command in when the kernel has no vcan: user-mode
Linux (`run_uml`) and the qemu micro-VM of virtme-ng (`run_vm`), each with this machine's own
userland, a vcan0 inside, the command's exit code out and nothing left running; and what a guest
is given of the host: the folders it shows (`visible_folders`, `tmp_binds`), the environment and
folder its command runs in (`command_lines`), where its script lies (`script_folder`).
"""

from __future__ import annotations

import contextlib
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import IO

from hilrig import resources
from hilrig.errors import BusUnavailableError

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


Say = Callable[[str], None]


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


DEFAULT_MEMORY = "4G"
"""A guest's memory unless $HIL_VM_MEMORY says (UML's is a sparse file in TMPDIR)."""
EMULATED_CPU = "max,erms=off"
"""qemu's -cpu under software emulation ($HIL_VM_CPU): with ERMS glibc and the kernel copy memory
with `rep movsb`, which qemu emulates a byte at a time (64 KiB copies 0.43 GB/s against 2.8)."""
EMULATED_KERNEL_ARGS = "tsc=reliable"
"""The emulated guest's kernel arguments ($HIL_VM_KERNEL_ARGS): its TSC check fails under emulation
and it falls back to the HPET, every clock read a trip into qemu; qemu's TSCs are one clock."""
KVM_PROBE_S = 25
VCAN_UP = "modprobe vcan && ip link add dev vcan0 type vcan && ip link set up vcan0 && ip link set up lo"
"""A guest's shell line that makes its vcan0 (and its loopback) up."""


def find_vm_kernel() -> Path | None:
    """$HIL_VM_KERNEL, else the newest stock Debian kernel with a vcan module (not `cloud`)."""
    if os.environ.get("HIL_VM_KERNEL"):
        return Path(os.environ["HIL_VM_KERNEL"])
    kernels = sorted(Path("/boot").glob("vmlinuz-*-amd64"), key=lambda k: _version_key(k.name), reverse=True)
    for kernel in kernels:
        version = kernel.name.removeprefix("vmlinuz-")
        if any(Path("/lib/modules", version).rglob("vcan.ko*")):
            return kernel
    return None


def _version_key(text: str) -> list[int]:
    return [int(n) for n in re.findall(r"\d+", text)]


def find_uml_kernel() -> Path | None:
    """$HIL_UML_KERNEL, else linux.uml of the running Python environment (the checkout's
    tools/uml-kernel puts a newer one there), else on PATH; only one whose modules hold vcan."""
    spelled = os.environ.get("HIL_UML_KERNEL")
    kernel = Path(spelled) if spelled else find_tool("linux.uml")
    if kernel is None or not os.access(kernel, os.X_OK):
        return None
    version = uml_version(kernel)
    if version is None or not any((uml_modules(kernel) / version).rglob("vcan.ko*")):
        return None
    return kernel


def uml_version(kernel: Path) -> str | None:
    try:
        done = subprocess.run([kernel, "--version"], capture_output=True, text=True, timeout=20, check=False)
    except (OSError, subprocess.TimeoutExpired):
        return None
    return done.stdout.strip() or None if done.returncode == 0 else None


def uml_modules(kernel: Path) -> Path:
    """The modules of a user-mode-linux package's kernel: usr/lib/uml/modules beside its usr/bin."""
    return kernel.resolve().parent.parent / "lib" / "uml" / "modules"


def uml_options(version: str) -> list[str]:
    """Since 6.16 a guest's system calls can be trapped by seccomp instead of ptrace: fewer host
    context switches a call."""
    numbers = [*_version_key(version)[:2], 0, 0]
    return ["seccomp=on"] if (numbers[0], numbers[1]) >= (6, 16) else []


def _stop_group(process: subprocess.Popen[bytes]) -> None:
    """The process and its process group killed, and reaped."""
    for kill in (lambda: os.killpg(process.pid, signal.SIGKILL), process.kill):
        with contextlib.suppress(ProcessLookupError, PermissionError):
            kill()
    process.wait()


def uml_script(
    command: Sequence[str], cwd: Path, folders: Sequence[Path], version: str, rc_file: Path, kernel: Path
) -> str:
    """The guest's init (PID 1): its own /proc, /sys, /run and /tmp over the shared root, the
    host's folders under /tmp that must be seen put back, the kernel's modules where modprobe
    looks, vcan0, the command, its exit code into `rc_file` (the kernel's own exit status says
    nothing of it), then power off."""
    binds = tmp_binds(folders)
    lines = [
        "#!/bin/sh",
        "mount -t proc proc /proc && mount -t sysfs sysfs /sys",
        "mount -t tmpfs tmpfs /run",
    ]
    if binds is not None:
        lines.append("mkdir -p /run/host-tmp && mount --bind /tmp /run/host-tmp && mount -t tmpfs tmpfs /tmp")
        for top in binds:
            inside = shlex.quote(str(Path("/run/host-tmp") / top.relative_to("/tmp")))
            lines.append(f"mkdir -p {shlex.quote(str(top))} && mount --bind {inside} {shlex.quote(str(top))}")
    lines += [
        "mkdir -p /dev/pts /dev/shm && mount -t devpts devpts /dev/pts && mount -t tmpfs tmpfs /dev/shm",
        f"mount --bind {shlex.quote(str(uml_modules(kernel)))} /lib/modules",
        # The command's output on a serial line of its own (the kernel's stays on the console,
        # discarded); no CR before each LF in logs.
        "exec >/dev/ttyS0 2>&1 && stty -onlcr",
        f"if {VCAN_UP}; then",
        # Through a pipe, as in the VM: the command sees no terminal (no colours in a CI log).
        "{ (",
        *command_lines(command, cwd, f"uml:{version}"),
        f") </dev/null; echo $? > {shlex.quote(str(rc_file))}; }} 2>&1 | cat",
        "fi",
        "poweroff -f >/dev/null 2>&1",
    ]
    return "\n".join(lines) + "\n"


def tmp_said(folders: Sequence[Path]) -> str:
    """How the guest's /tmp relates to the host's, for the line that names the path taken."""
    binds = tmp_binds(folders)
    if binds is None:
        return "the host's /tmp"
    if not binds:
        return "a /tmp of its own"
    return f"a /tmp of its own with the host's {', '.join(map(str, binds))}"


def run_uml(command: Sequence[str], cwd: Path, folders: Sequence[Path], say: Say) -> int:
    kernel = find_uml_kernel()
    if kernel is None:
        raise BusUnavailableError(f"no user-mode Linux with vcan here: install {INSTALL_HINT}")
    version = uml_version(kernel) or "?"
    where = f"user-mode Linux (kernel {version}, one core) with SocketCAN vcan0, {tmp_said(folders)}"
    say(f"bus path: {where}; booting...")
    record_path(f"user-mode Linux vcan0 (kernel {version})")
    with _script() as script:
        rc_file = Path(f"{script}.rc")
        script.write_text(uml_script(command, cwd, folders, version, rc_file, kernel))
        memory = os.environ.get("HIL_VM_MEMORY") or DEFAULT_MEMORY
        argv = [str(kernel), *uml_options(version), f"mem={memory}", "root=/dev/root", "rootfstype=hostfs",
                "hostfs=/", "rw", f"init={script}", "con=null", "ssl=null", "ssl0=null,fd:1",
                "quiet"]  # fmt: skip
        started = time.monotonic()
        # The kernel puts itself and its processes in a process group of their own, out of reach
        # of the terminal's Ctrl-C: an interrupt here ends that group, so nothing is left running.
        process = subprocess.Popen(argv, stdin=subprocess.DEVNULL)
        try:
            status = process.wait()
        except BaseException:
            _stop_group(process)
            raise
        if status == 0:
            try:
                status = int(rc_file.read_text().strip())
            except (OSError, ValueError):
                raise BusUnavailableError(
                    "user-mode Linux stopped before the command ended (vcan could not be set up?)"
                ) from None
    say(f"user-mode Linux finished in {time.monotonic() - started:.0f} s, exit code {status}")
    return status


class _script:
    """A new executable script file in the guests' script folder, removed afterwards."""

    def __enter__(self) -> Path:
        handle, name = tempfile.mkstemp(prefix="inner.", suffix=".sh", dir=script_folder())
        os.close(handle)
        self.path = Path(name)
        self.path.chmod(0o755)
        return self.path

    def __exit__(self, *_: object) -> None:
        self.path.unlink(missing_ok=True)
        Path(f"{self.path}.rc").unlink(missing_ok=True)


def kvm_works(kernel: Path, say: Say) -> bool:
    """/dev/kvm can exist while a guest under it hangs before printing anything, so KVM is used
    only when a short probe boot completes. The verdict is the machine's, cached until the next
    boot (or another kernel) in $XDG_CACHE_HOME/hilrig/kvm-probe."""
    if not os.access("/dev/kvm", os.W_OK):
        return False
    cache = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "hilrig" / "kvm-probe"
    try:
        boot_id = Path("/proc/sys/kernel/random/boot_id").read_text().strip()
    except OSError:
        boot_id = ""
    key = f"{kernel} {boot_id}"
    try:
        cached = cache.read_text().splitlines()
        if len(cached) >= 2 and cached[0] == key:
            return cached[1] == "yes"
    except OSError:
        pass
    say(f"probing KVM (one-off, at most {KVM_PROBE_S} s)...")
    verdict = _kvm_probe(kernel)
    try:
        cache.parent.mkdir(parents=True, exist_ok=True)
        temporary = cache.with_name(f"{cache.name}.{os.getpid()}")
        temporary.write_text(f"{key}\n{'yes' if verdict else 'no'}\n")
        temporary.replace(cache)
    except OSError:
        pass
    say(f"KVM works: {'yes' if verdict else 'no'}")
    return verdict


def _kvm_probe(kernel: Path) -> bool:
    """A bare boot first: under KVM the kernel's first console line comes within a second, where a
    guest hangs nothing comes; then a full virtme-ng boot proves the rest."""
    qemu = ["qemu-system-x86_64", "-enable-kvm", "-m", "256M", "-display", "none", "-no-reboot",
            "-serial", "stdio", "-kernel", str(kernel), "-append", "console=ttyS0 panic=-1"]  # fmt: skip
    try:
        done = subprocess.run(qemu, stdin=subprocess.DEVNULL, capture_output=True, timeout=5, check=False)
        printed = done.stdout
    except subprocess.TimeoutExpired as expired:
        printed = expired.stdout or b""
    except OSError:
        return False
    vng = find_tool("vng")
    if b"Linux version" not in printed or vng is None:
        return False
    probe = [str(vng), "--run", str(kernel), "--user", "root", "--memory", "512M", "--exec", "true"]
    try:
        boot = subprocess.run(
            probe, stdin=subprocess.DEVNULL, capture_output=True, timeout=20, check=False, env=_vm_env()
        )
    except (OSError, subprocess.TimeoutExpired):
        return False
    return boot.returncode == 0


def _vm_env() -> dict[str, str]:
    """virtme-ng execs qemu through its helper scripts beside it: they must be on PATH."""
    vng = find_tool("vng")
    folder = str(vng.parent) if vng is not None else ""
    return os.environ | {"PATH": f"{folder}:{os.environ.get('PATH', '')}"}


def _virtiofsd_works() -> bool:
    tool = find_tool("virtiofsd")
    if tool is None:
        return False
    try:
        return (
            subprocess.run([tool, "--version"], capture_output=True, timeout=10, check=False).returncode == 0
        )
    except (OSError, subprocess.TimeoutExpired):
        return False


def run_vm(command: Sequence[str], cwd: Path, folders: Sequence[Path], kvm: str, say: Say) -> int:
    kernel = find_vm_kernel()
    if kernel is None:
        raise BusUnavailableError(
            f"this kernel has no vcan and no Debian kernel with vcan is installed: install {INSTALL_HINT}"
        )
    vng = find_tool("vng")
    if vng is None:
        raise BusUnavailableError(
            "virtme-ng (vng) is missing: pip install virtme-ng (the checkout: make deps)"
        )
    for tool, package in (("qemu-system-x86_64", "qemu-system-x86"), ("busybox", "busybox-static")):
        if find_tool(tool) is None:
            raise BusUnavailableError(f"{tool} is missing: apt-get install {package}")
    version = kernel.name.removeprefix("vmlinuz-")
    accel: list[str] = []
    if kvm == "no" or (kvm == "auto" and not kvm_works(kernel, say)):
        accel = ["--disable-kvm"]
    how = "KVM"
    if accel:
        cpu = os.environ.get("HIL_VM_CPU") or EMULATED_CPU
        kernel_args = os.environ.get("HIL_VM_KERNEL_ARGS", EMULATED_KERNEL_ARGS)
        accel.append(f"--qemu-opts=-cpu {cpu}")
        how = f"software emulation, cpu {cpu}"
        if kernel_args:
            accel += ["--append", kernel_args]
            how += f", {kernel_args}"
    # virtme-ng shares the files over virtiofs when the Rust virtiofsd is on its PATH (the
    # checkout's tools/deps builds one into .venv/bin), else over 9p, a round trip per access.
    if not _virtiofsd_works() and resources.CHECKOUT is not None:
        subprocess.run([resources.CHECKOUT / "tools" / "deps", "--virtiofsd"], stdout=sys.stderr, check=False)
    files = "files over virtiofs" if _virtiofsd_works() else "files over 9p: slower, build virtiofsd (Rust)"
    say(f"bus path: micro-VM (kernel {version}, {how}, {files}) with SocketCAN vcan0; booting...")
    record_path(f"micro-VM vcan0 (kernel {version}, {how}, {files.partition(':')[0]})")
    binds = tmp_binds(folders)
    rwdirs = _outermost([cwd, *([Path("/tmp")] if binds is None else binds), script_folder()])
    if resources.CHECKOUT is not None:
        rwdirs = _outermost([*rwdirs, resources.CHECKOUT])
    cpus = os.environ.get("HIL_VM_CPUS") or str(os.cpu_count() or 1)
    memory = os.environ.get("HIL_VM_MEMORY") or DEFAULT_MEMORY
    with _script() as script:
        lines = ["#!/bin/sh", "set -e", VCAN_UP, *command_lines(command, cwd, f"vm:{version}"), "exit $?"]
        script.write_text("\n".join(lines) + "\n")
        argv = [str(vng), "--run", str(kernel), "--user", "root", *accel, "--cpus", cpus, "--memory", memory,
                *(f"--rwdir={d}" for d in rwdirs), "--exec", str(script)]  # fmt: skip
        started = time.monotonic()
        # qemu opens the guest's console outputs by path (/proc/self/fd/1), which truncates a
        # file: it gets pipes, copied out here. A session of its own: Ctrl-C reaches us alone,
        # and ends the whole group.
        process = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                   stderr=subprocess.PIPE, env=_vm_env(), start_new_session=True)  # fmt: skip
        assert process.stdout is not None and process.stderr is not None
        copies = [_copy(process.stdout, sys.stdout.buffer), _copy(process.stderr, sys.stderr.buffer)]
        try:
            status = process.wait()
            for copy in copies:
                copy.join()
        except BaseException:
            _stop_group(process)
            raise
    say(f"micro-VM finished in {time.monotonic() - started:.0f} s, exit code {status}")
    return status


def _outermost(folders: Sequence[Path]) -> list[Path]:
    """The folders without any that lies in another."""
    unique = sorted(set(folders))
    return [f for f in unique if not any(f != o and f.is_relative_to(o) for o in unique)]


def _copy(source: IO[bytes], target: IO[bytes]) -> threading.Thread:
    def pump() -> None:
        while chunk := source.read1(65536):  # type: ignore[attr-defined]
            target.write(chunk)
            target.flush()

    thread = threading.Thread(target=pump, daemon=True)
    thread.start()
    return thread
