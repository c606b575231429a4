"""The firmware process: `joint-firmware` started inside a private bus, its log kept in a file.

    with PrivateBus() as bus, Firmware(bus, node_id=0x10, log_path=tmp / "firmware.log") as fw:
        with bus.open() as can_bus, Rig(can_bus, liveness=fw.check) as rig:
            rig.run(seconds=1.0)

`check()` raises FirmwareError with the last lines of the log once the process has died;
the rig calls it while it waits for TPDOs, so a crash reads as a crash, not as a timeout.
"""

from __future__ import annotations

import contextlib
import re
import signal
import subprocess
from collections import deque
from collections.abc import Sequence
from pathlib import Path
from types import TracebackType
from typing import IO, Any, Protocol, Self

from hilrig import resources
from hilrig.engine.driver import ProcessActivity, process_activity
from hilrig.engine.timing import TimingMode
from hilrig.errors import FirmwareError
from hilrig.session import baremetal

DEFAULT_EXECUTABLE = resources.DEFAULT_FIRMWARE
LOG_TAIL_LINES = 20
_STOP_LINE = re.compile(r"^\S+: stopped after (\d+) cycles; (.*)$", re.MULTILINE)


def parse_stop_line(text: str) -> tuple[str, dict[str, int]] | None:
    """The firmware's stop line (printed when it stops cleanly) in a log's `text`, and its
    counters by name ({"cycles": 812, "overruns": 0, "frames received": 4100, ...}); None
    when the log has none (the firmware was killed or crashed)."""
    match = _STOP_LINE.search(text)
    if match is None:
        return None
    counters = {"cycles": int(match.group(1))}
    for part in re.split(r"[;,] ", match.group(2)):
        name, _, value = part.strip().rpartition(" ")
        with contextlib.suppress(ValueError):
            counters[name] = int(value)
    return match.group(0), counters


class Launcher(Protocol):
    """Starts a process on the bus the firmware must use (`netns.PrivateBus` is one)."""

    channel: str

    def popen(self, argv: list[str], **kwargs: Any) -> subprocess.Popen[Any]: ...


def firmware_argv(
    executable: Path,
    channel: str,
    node_id: int,
    period_us: int | None,
    params_file: Path | None = None,
    extra_args: Sequence[str] = (),
    *,
    mode: TimingMode | str = TimingMode.LOCKSTEP,
    image_dir: Path | None = None,
) -> list[str]:
    """The firmware's command line in `mode` (its --mode word: `firmware_mode`; options exactly as
    the firmware defines),
    then `extra_args` as given (e.g. a fault-injection option of `joint-firmware --help`).
    `period_us` None: the firmware's own default (its table's [node] period_us)."""
    argv = [str(executable), "--can", channel, "--node-id", str(node_id), "--mode", firmware_mode(mode)]
    if period_us is not None:
        argv += ["--period-us", str(period_us)]
    if params_file is not None:
        argv += ["--params", str(params_file)]
    if image_dir is not None:
        argv += ["--image-dir", str(image_dir)]
    return [*argv, *extra_args]


FIRMWARE_MODES = {TimingMode.LOCKSTEP: "lockstep", TimingMode.REALTIME: "free"}
"""The firmware's --mode word for each timing mode: one cycle per SYNC, or its own
absolute-deadline timer beside a real-time rig. The words appear on its command line only."""


def firmware_mode(mode: TimingMode | str) -> str:
    """The firmware's --mode word of a timing mode ("lockstep" or "realtime")."""
    try:
        return FIRMWARE_MODES[TimingMode(mode)]
    except ValueError:
        modes = ", ".join(TimingMode)
        raise ValueError(f"timing mode {mode!r}: expected one of {modes} (`TimingMode`)") from None


class Firmware:
    """One firmware process. stdout and stderr go to `log_path`; stop() is SIGTERM, then
    SIGKILL after `term_timeout_s`. `extra_args` go last on its command line. `image_dir`: the
    firmware's program download directory (--image-dir, created here): an image flashed into it
    (CiA 302-3) re-executes the process in place, same pid, so stop() and kill() still reach it.
    `platform`: "linux" (the process above) or "qemu-virt" (`executable` is then the bare-metal
    image, run by qemu-system-arm on the launcher's channel: hilrig.session.baremetal; its
    parameters in a pflash file beside `params_file`; no program download)."""

    def __init__(
        self,
        launcher: Launcher,
        *,
        node_id: int,
        log_path: Path,
        period_us: int | None = None,
        params_file: Path | None = None,
        extra_args: Sequence[str] = (),
        executable: Path = DEFAULT_EXECUTABLE,
        term_timeout_s: float = 5.0,
        mode: TimingMode | str = TimingMode.LOCKSTEP,
        image_dir: Path | None = None,
        platform: str = baremetal.LINUX,
    ) -> None:
        self.launcher = launcher
        self.mode = TimingMode(mode)
        self.platform = baremetal.check_platform(platform)
        self.flash: Path | None = None
        if self.platform == baremetal.QEMU_VIRT:
            self.image_dir = None
            self.flash = baremetal.flash_file(params_file) if params_file is not None else None
            self.argv = baremetal.qemu_argv(
                executable,
                launcher.channel,
                node_id=node_id,
                period_us=period_us,
                mode=firmware_mode(self.mode),
                flash=self.flash,
                extra_args=extra_args,
            )
        else:
            self.image_dir = image_dir
            self.argv = firmware_argv(
                executable,
                launcher.channel,
                node_id,
                period_us,
                params_file,
                extra_args,
                mode=self.mode,
                image_dir=image_dir,
            )
        self.executable = executable
        self.log_path = log_path
        self.term_timeout_s = term_timeout_s
        self.process: subprocess.Popen[Any] | None = None
        self._log: IO[bytes] | None = None

    def start(self, *, append_log: bool = False) -> None:
        if self.process is not None:
            raise FirmwareError(f"{self.executable.name} already started (pid {self.process.pid})")
        if not self.executable.exists():
            build = "make baremetal" if self.platform == baremetal.QEMU_VIRT else "cmake --build build"
            raise FirmwareError(f"{self.executable} does not exist: build the firmware first ({build})")
        self.log_path.parent.mkdir(parents=True, exist_ok=True)
        if self.image_dir is not None:
            self.image_dir.mkdir(parents=True, exist_ok=True)
        if self.platform == baremetal.QEMU_VIRT:
            self.argv[0] = baremetal.require_qemu(self.argv[0])
            if self.flash is not None:
                baremetal.prepare_flash(self.flash)
        self._log = self.log_path.open("ab" if append_log else "wb")
        try:
            self.process = self.launcher.popen(
                self.argv, stdin=subprocess.DEVNULL, stdout=self._log, stderr=subprocess.STDOUT
            )
        except OSError as error:
            self._log.close()
            raise FirmwareError(f"cannot start {' '.join(self.argv)}: {error}") from error

    @property
    def running(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def check(self) -> None:
        """Raise FirmwareError (with the log's last lines) if the process is not running."""
        if self.process is None:
            raise FirmwareError(f"{self.executable.name} was never started")
        code = self.process.poll()
        if code is not None:
            raise FirmwareError(
                f"{self.executable.name} (pid {self.process.pid}) "
                f"{describe_exit(code)}; last lines of {self.log_path}:\n"
                f"{self.log_tail()}"
            )

    def activity(self) -> ProcessActivity | None:
        """The process's CPU time and sleep state (the lockstep hang guard's view of it); None
        when it is not running."""
        process = self.process
        return process_activity(process.pid) if process is not None else None

    def log_tail(self, lines: int = LOG_TAIL_LINES) -> str:
        try:
            with self.log_path.open("r", errors="replace") as log:
                return "".join(deque(log, maxlen=lines)).rstrip("\n") or "(log is empty)"
        except OSError as error:
            return f"(cannot read log: {error.strerror})"

    def kill(self) -> None:
        """SIGKILL now, as a crash or a pulled plug would end it; `check()` then reports it."""
        if self.process is not None and self.process.poll() is None:
            self.process.kill()
            self.process.wait()

    def restart(self) -> None:
        """SIGKILL the process and start the same command again; the log is appended to,
        with a line that marks the restart."""
        self.kill()
        if self._log is not None:
            self._log.close()
            self._log = None
        self.process = None
        with self.log_path.open("ab") as log:
            log.write(b"---- hilrig: firmware killed with SIGKILL and started again ----\n")
        self.start(append_log=True)

    def stop(self) -> int | None:
        """SIGTERM, wait up to term_timeout_s, then SIGKILL. Returns the exit code
        (negative: killed by that signal), None if never started."""
        process = self.process
        if process is None:
            return None
        try:
            if process.poll() is None:
                process.send_signal(signal.SIGTERM)
                try:
                    process.wait(self.term_timeout_s)
                except subprocess.TimeoutExpired:
                    process.kill()
                    process.wait()
            return process.returncode
        finally:
            if self._log is not None:
                self._log.close()
                self._log = None

    def __enter__(self) -> Self:
        self.start()
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, traceback: TracebackType | None
    ) -> None:
        self.stop()


def describe_exit(code: int) -> str:
    """'exited with code 3' or 'was killed by SIGSEGV'."""
    if code < 0:
        try:
            return f"was killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"was killed by signal {-code}"
    return f"exited with code {code}"
