"""What every step of `make bench` (tools/bench.py) shares: where the project is, the progress
line, JSON written atomically, the machine's description, a measurement's time budget
(`run_within`), and the running of a probe, so that one that fails (a timeout under callgrind on a
busy host, a non-zero exit) costs its own figure and never the run (`run_probe`, `ProbeError`,
`NotMeasured`).
"""

from __future__ import annotations

import contextlib
import json
import os
import platform
import subprocess
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from time import perf_counter
from typing import Any, TypeVar

from hilrig import resources

_T = TypeVar("_T")
ROOT = resources.CHECKOUT if resources.CHECKOUT is not None else Path.cwd()
"""The checkout the bench measures (its build/, firmware/, protocol/): the bench runs from one."""
LONG_TRACE_CYCLES = 60_000
"""The long traced run: 60 s at 1 kHz, a trace that must stay viewable."""


_STARTED = time.monotonic()


def say(text: str) -> None:
    print(f"bench [{time.monotonic() - _STARTED:5.0f} s]: {text}", flush=True)


def write_json_atomically(path: Path, data: Any) -> None:
    """temp file + rename: an interrupted run never leaves a half-written file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, temp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as out:
            json.dump(data, out, indent=2)
            out.write("\n")
        os.replace(temp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(temp)
        raise


def machine() -> dict[str, Any]:
    model = platform.processor() or platform.machine()
    with contextlib.suppress(OSError), open("/proc/cpuinfo") as cpuinfo:
        for line in cpuinfo:
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    return {"cpu": model, "cores": os.cpu_count(), "kernel": platform.release()}


PROBE_TIMEOUT_S = 1800.0
"""A probe (a benchmark, a count under callgrind) still running after this is stopped and not
measured: callgrind slows Python many times over, and a busy host stretches that further."""
STDERR_TAIL_LINES = 12
"""Lines of a failed probe's stderr its error text keeps (the end, where the reason is)."""
NOT_MEASURED = "not measured"


class ProbeError(RuntimeError):
    """A probe gave no figure: it timed out, exited non-zero, or could not start. The text says
    which, the command, and the tail of the probe's stderr."""


def _stderr_tail(stderr: str | bytes | None) -> str:
    if isinstance(stderr, bytes):  # TimeoutExpired keeps bytes even with text=True
        stderr = stderr.decode("utf-8", "replace")
    lines = (stderr or "").strip().splitlines()[-STDERR_TAIL_LINES:]
    return "\nstderr (end):\n" + "\n".join(f"  {line}" for line in lines) if lines else "\nno stderr"


def run_probe(
    command: Sequence[str],
    *,
    timeout_s: float = PROBE_TIMEOUT_S,
    env: dict[str, str] | None = None,
    cwd: Path | None = None,
    show_stdout: bool = False,
) -> str:
    """Runs one probe (in `cwd`, else here) and returns its stdout ("" when `show_stdout` lets it
    go to the console); ProbeError when it times out, exits non-zero or cannot start, with its
    stderr's tail."""
    shown = " ".join(Path(command[0]).name if n == 0 else part for n, part in enumerate(command))
    try:
        done = subprocess.run(
            list(command),
            stdout=None if show_stdout else subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            timeout=timeout_s,
            env=env,
            cwd=cwd,
            check=False,
        )
    except subprocess.TimeoutExpired as error:
        raise ProbeError(f"{shown}: timed out after {timeout_s:g} s{_stderr_tail(error.stderr)}") from error
    except OSError as error:
        raise ProbeError(f"{shown}: could not start: {error}") from error
    if done.returncode != 0:
        raise ProbeError(f"{shown}: exit status {done.returncode}{_stderr_tail(done.stderr)}")
    return done.stdout or ""


def failure_text(error: Exception) -> str:
    """A probe's failure in words: a ProbeError's own text, else the exception's type and text."""
    return str(error) if isinstance(error, ProbeError) else f"{type(error).__name__}: {error}"


class NotMeasured(dict[str, str]):
    """Why each measurement that failed gave no figure, by name; saved in native.json and
    bus.json, so the report shows the error in the measurement's own row."""

    def attempt(self, name: str, measure: Callable[[], _T]) -> _T | None:
        """measure(), or None with the failure noted under `name`: one probe that fails (a
        timeout under callgrind on a busy host) costs its own figure, never the run."""
        try:
            return measure()
        except Exception as error:
            self[name] = failure_text(error)
            say(f"  {name}: {NOT_MEASURED}: {self[name].splitlines()[0]}")
            return None


class _BudgetSpent(Exception):
    """Raised between two cycles by `run_within`'s look at the clock: the measurement ends."""


def run_within(
    runner: Any, budget_s: float, cycles: int, *, finish: Callable[[], object] | None = None
) -> tuple[int, float]:
    """(cycles done, seconds) of `cycles` lockstep cycles of `runner` (a `Rig` or a `Robot`), then
    `finish()` (inside the time) if given. The clock is looked at before each cycle, as the
    floors look at it (`Timeline.before_each_cycle`), and no cycle starts past `budget_s`: a
    measurement whose cycles slow down (a loaded host, a stalling run) ends within one cycle of
    its budget, and says how many it measured."""
    start = perf_counter()
    deadline = start + budget_s
    done = 0
    armed = True

    def look(_: Any) -> None:
        nonlocal done
        if armed:
            if perf_counter() > deadline:
                raise _BudgetSpent
            done += 1

    runner.before_each_cycle(look)
    try:
        runner.run(cycles=cycles)
    except _BudgetSpent:
        pass
    finally:
        armed = False  # the hook stays the runner's: a later run() is not measured
    if finish is not None:
        finish()
    return done, perf_counter() - start


def bench_period_us() -> int:
    """The control period of the bench's runs: a run description's own (`RigRun.cycle_us`), the
    table's [node] period_us."""
    from hilrig.session.run import RigRun
    from hilrig.table import RigTable

    return RigRun().cycle_us(RigTable.load())


def rate_text(period_us: float) -> str:
    """A control period as the report names its rate: "1 kHz"."""
    return f"{1e3 / period_us:g} kHz"


def ratio_of(a: float, b: float) -> float:
    return a / b if b else float("nan")
