"""What a scenario spends outside its cycles: each step of opening and closing a HIL session,
timed, for one joint and for a robot. Run it where the scenarios run (inside the micro-VM here):

    tools/with-vcan -- .venv/bin/python tools/scenario_costs.py [--cycles 500] [--modules 4]

(`hilrig.apps.bench.scenario_costs`, a measurement of the bench's kind, but not in `make bench`).

It opens sessions through `hilrig.session.builder` exactly as the fixtures do and times the
builder's own steps by wrapping them (the private bus, the recorder, each firmware start, the
tracer, the rig's start), then the cycles, the close, and reading the trace back as a test does.
The interpreter's own start and imports come from `-X importtime`-free wall time of a fresh
`python -c 'import ...'` of what tests/conftest.py imports. A table on stdout, seconds.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

CONFTEST_IMPORTS = (
    "import can, canopen, pytest; import hilrig.session.builder, hilrig.expect, "
    "hilrig.observe.picture, hilrig.observe.sinks, hilrig.engine.robot"
)

spent: dict[str, float] = defaultdict(float)
counts: dict[str, int] = defaultdict(int)


@contextmanager
def timed(step: str) -> Iterator[None]:
    started = time.perf_counter()
    try:
        yield
    finally:
        spent[step] += time.perf_counter() - started
        counts[step] += 1


def wrap(owner: Any, name: str, step: str) -> None:
    original: Callable[..., Any] = getattr(owner, name)

    def timed_call(*args: Any, **kwargs: Any) -> Any:
        with timed(step):
            return original(*args, **kwargs)

    setattr(owner, name, timed_call)


def fresh_interpreter(code: str) -> float:
    started = time.perf_counter()
    subprocess.run([sys.executable, "-c", code], check=True)
    return time.perf_counter() - started


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cycles", type=int, default=500, help="cycles each session runs (default 500)")
    parser.add_argument("--modules", type=int, default=4, help="modules of the robot session (default 4)")
    args = parser.parse_args(argv)

    with timed("interpreter start, bare (python -c pass)"):
        fresh_interpreter("pass")
    with timed("interpreter start + the fixtures' imports"):
        fresh_interpreter(CONFTEST_IMPORTS)
    with timed("imports in this process (first time)"):
        import hilrig.session.builder as builder
        from hilrig.apps.gait import TravellingWave
        from hilrig.engine.rig import Rig
        from hilrig.engine.robot import Robot
        from hilrig.observe.reader import Trace
        from hilrig.session import netns
        from hilrig.session.run import RigRun, RobotRun, RunDescription, TraceRun
        from hilrig.table import RigTable

    wrap(netns.PrivateBus, "create", "private bus (netns + vcan0)")
    wrap(netns.PrivateBus, "close", "private bus removed")
    wrap(builder.RecorderProcess, "close", "recorder stopped, log renamed")
    wrap(builder, "RecorderProcess", "recorder process started (ready)")
    wrap(builder, "_start_firmware", "firmware process started")
    wrap(builder.Firmware, "stop", "firmware stopped (SIGTERM, stop line)")
    wrap(builder, "_tracer", "tracer opened (rerun imported the first time)")
    wrap(Rig, "start", "rig start: boot-up, SDO configuration, operational")
    wrap(Rig, "close", "rig closed")
    wrap(Robot, "start", "robot start: every module booted and configured")
    table = RigTable.load()
    with tempfile.TemporaryDirectory() as scratch:
        joint = RunDescription(TraceRun(Path(scratch) / "joint"), rig=RigRun(seed=1))
        robot = joint.replace(trace=TraceRun(Path(scratch) / "robot"), robot=RobotRun(args.modules))
        for label, run in (("joint", joint), ("robot", robot)):
            with timed(f"{label}: session opened (all of the above)"):
                session = builder.open_session(run, table=table)
            try:
                with timed(f"{label}: {args.cycles} cycles"):
                    if session.robot is not None:
                        TravellingWave().drive(session.robot)
                        session.robot.run(cycles=args.cycles)
                    else:
                        assert session.rig is not None
                        session.rig.run(cycles=args.cycles)
            finally:
                with timed(f"{label}: session closed (all of the above)"):
                    session.close()
            with timed(f"{label}: trace read back"):
                Trace.read(run.out_dir / "trace.rrd")
    width = max(len(step) for step in spent)
    print(f"{'step':<{width}}  {'calls':>5}  {'seconds':>8}")
    for step, seconds in spent.items():
        print(f"{step:<{width}}  {counts[step]:>5}  {seconds:>8.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
