"""What tracing costs the lockstep loop, as ratios measured side by side in one run.

    .venv/bin/python rig/bench_trace.py [--cycles 2000]

1. The hot-path call alone: `Tracer.log_cycle` with a real cycle's dicts, in a tight loop, for
   three strategies: per-cycle `rr.log` (one call per entity, the naive way), column batches
   sent inline every N cycles, column batches sent by the background thread (the default).
   All write to a .rrd in a temporary folder.
2. Whole lockstep cycles of a Rig against the in-process fake node (virtual bus), without a
   tracer and with each strategy.
"""

from __future__ import annotations

import argparse
import itertools
import tempfile
import time
from collections.abc import Callable, Mapping
from pathlib import Path

import can

from hilrig.fake_node import FakeJointNode
from hilrig.physics import JointParams, JointState
from hilrig.rig import Rig
from hilrig.table import RigTable
from hilrig.trace import CYCLE_TIMELINE, SIM_TIME_TIMELINE, TRUTH_QUANTITIES, Tracer, TraceSink, truth_path

_channels = itertools.count()


class PerCycleTracer(Tracer):
    """The naive way, for comparison: one `rr.log` per entity per cycle on the loop's thread."""

    def log_cycle(
        self,
        cycle: int,
        t: float,
        received: Mapping[str, float | int],
        sent: Mapping[str, float | int],
        truth: JointState,
    ) -> None:
        rr, rec = self._rr, self.recording
        rec.set_time(CYCLE_TIMELINE, sequence=cycle)
        rec.set_time(SIM_TIME_TIMELINE, duration=t)
        for values in (received, sent):
            for name, value in values.items():
                rec.log(self._paths[name], rr.Scalars(float(value)))
        for quantity in TRUTH_QUANTITIES[:-1]:
            rec.log(truth_path(quantity), rr.Scalars(getattr(truth, quantity)))
        self.cycles_logged += 1


Factory = Callable[[Path, RigTable], Tracer | None]
STRATEGIES: dict[str, Factory] = {
    "no tracer": lambda path, table: None,
    "rr.log per cycle": lambda path, table: PerCycleTracer(TraceSink.rrd(path), table, blueprint=None),
    "columns, inline every 500": lambda path, table: Tracer(
        TraceSink.rrd(path), table, blueprint=None, background=False
    ),
    "columns, background thread": lambda path, table: Tracer(TraceSink.rrd(path), table, blueprint=None),
}


def bench_hot_path(table: RigTable, cycles: int, folder: Path) -> dict[str, float]:
    """Seconds per log_cycle call (including close(), which sends what is pending)."""
    received = {
        "motor_duty": 2000,
        "led_pattern": 1,
        "motor_velocity": 1.0,
        "output_velocity": 0.1,
        "joint_torque": 0.5,
        "spring_deflection": 0.01,
        "motor_duty_command": 0.2,
        "velocity_controller_output": 0.2,
        "torque_controller_output": 0.0,
        "output_position": 1.0,
        "safe_state": 0.0,
        "fault_flags": 0.0,
        "watchdog_tripped": 0.0,
        "motor_current": 0.3,
    }
    sent = {
        "motor_encoder_counts": 100,
        "output_encoder_counts": 10,
        "thermistor_adc": 2000,
        "motor_current_adc": 300,
        "velocity_setpoint": 5.0,
        "torque_setpoint": 0.0,
    }
    truth = JointState(0.0, 1.0, 2.0, 0.1, 0.2, 0.3, 25.0, 0.01, 0.5, 1.2, 0.2)
    results: dict[str, float] = {}
    for name, factory in STRATEGIES.items():
        if name == "no tracer":
            continue
        tracer = factory(folder / f"hot-{len(results)}.rrd", table)
        assert tracer is not None
        start = time.perf_counter()
        for n in range(cycles):
            tracer.log_cycle(n, n * 1e-3, received, sent, truth)
        loop = time.perf_counter() - start
        tracer.close()
        results[name] = loop / cycles
    return results


def bench_lockstep(table: RigTable, cycles: int, folder: Path, rounds: int = 3) -> dict[str, float]:
    """Seconds per lockstep cycle (best of `rounds`, strategies interleaved)."""
    best: dict[str, float] = {}
    for round_ in range(rounds):
        for name, factory in STRATEGIES.items():
            channel = f"bench-trace-{next(_channels)}"
            rig_bus, fake_bus = (can.Bus(interface="virtual", channel=channel) for _ in range(2))
            fake = FakeJointNode(fake_bus, table=table)
            tracer = factory(folder / f"lockstep-{round_}-{len(best)}.rrd", table)
            rig = Rig(rig_bus, table=table, params=JointParams.fast_thermal(), tracer=tracer)
            fake.boot()
            rig.start()
            rig.set("velocity_setpoint", 5.0)
            start = time.perf_counter()
            rig.run(cycles=cycles)
            elapsed = time.perf_counter() - start
            rig.close()
            fake.close()
            if tracer is not None:
                tracer.close()
            rig_bus.shutdown()
            fake_bus.shutdown()
            best[name] = min(best.get(name, float("inf")), elapsed / cycles)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--cycles", type=int, default=2000)
    args = parser.parse_args()
    table = RigTable.load()
    with tempfile.TemporaryDirectory(prefix="bench-trace-") as folder:
        hot = bench_hot_path(table, args.cycles * 5, Path(folder))
        print(f"log_cycle alone ({args.cycles * 5} calls, 20 fields + 11 truth per cycle):")
        base = hot["columns, background thread"]
        for name, seconds in hot.items():
            print(f"  {name:30s} {seconds * 1e6:8.2f} us/cycle  {seconds / base:6.1f}x")
        full = bench_lockstep(table, args.cycles, Path(folder))
        print(f"whole lockstep cycles against the fake node ({args.cycles} cycles, best of 3):")
        base = full["no tracer"]
        for name, seconds in full.items():
            print(f"  {name:30s} {seconds * 1e6:8.1f} us/cycle  {seconds / base:6.2f}x")


if __name__ == "__main__":
    main()
