"""`tools/bench.py bus`: every bus measurement (`bus_measure.BusBench`) on one private
bus (a network namespace with its own vcan0; root, so through tools/with-vcan), in alternating
rounds, and the bus load of the default PDO mapping. Writes <out>/bus.json; a measurement that
fails leaves its error under "not_measured".
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from hilrig.apps.bench.bus_measure import BusBench
from hilrig.apps.bench.common import NotMeasured, machine, ratio_of, say, write_json_atomically

BUS_MEASUREMENTS = ("lockstep", "timed_bus", "robot", "long_trace", "sdo", "recorder_upload", "free_running")
"""What `tools/bench.py bus` measures, in order (`--only NAME` picks some)."""
ROBOT_SIZES = (1, 4, 8, 16)
"""Robots measured side by side: how the cost of a lockstep cycle grows with the modules."""


LOCKSTEP_ROUNDS = 6
"""Rounds of the lockstep kinds (Rig untraced and traced, the floors), alternating, best of each.
The emulated VM's rate moves a lot between rounds of one run when the host is busy: enough rounds
that each kind gets at least one undisturbed one."""


RIG_PAIRS_PER_ROUND = 4
"""Untraced/traced pairs of Rig runs per round (an even number: each kind first in half). On a
shared host one pair's ratio scatters widely, so the goal is judged on the median of many pairs."""


def rig_pair_orders(round_: int) -> list[tuple[str, str]]:
    """The Rig's runs in round `round_` (from 1): RIG_PAIRS_PER_ROUND pairs of an untraced and a
    traced run, each kind first in half of them (untraced, traced, traced, untraced, ... in odd
    rounds; the mirror in even ones), so that neither kind always runs right after the other's
    teardown, and each pair is two runs back to back: their ratio is what tracing costs, whatever
    the host's drift."""
    pairs = [("rig", "rig_traced"), ("rig_traced", "rig")] * (RIG_PAIRS_PER_ROUND // 2)
    return pairs if round_ % 2 else pairs[::-1]


def _lockstep_runs(bench: BusBench, args: argparse.Namespace) -> dict[str, Any]:
    say(
        f"lockstep: {args.rounds} rounds of {args.cycles} cycles: Rig untraced, Rig traced, "
        "raw-socket floor, the engine's exchange alone, python-can floor, alternating"
    )
    kinds = ("rig", "rig_traced", "floor", "engine_floor", "python_can")
    rates: dict[str, list[float]] = {kind: [] for kind in kinds}
    measured: list[dict[str, Any]] = []
    for round_ in range(1, args.rounds + 1):
        orders = rig_pair_orders(round_)
        pairs = [
            {
                kind: bench.rig_rate(args.cycles, args.warmup, args.budget_s, traced=kind == "rig_traced")
                for kind in order
            }
            for order in orders
        ]
        got = {
            "floor": bench.floor_rate(args.cycles, args.warmup, args.budget_s),
            "engine_floor": bench.engine_floor_rate(args.cycles, args.warmup, args.budget_s),
            "python_can": bench.python_can_rate(args.cycles, args.warmup, args.budget_s),
        }
        for kind in kinds:
            runs = [pair[kind] for pair in pairs] if kind in pairs[0] else [got[kind]]
            rates[kind] += [rate for rate, _ in runs]
            measured.append({"round": round_, "kind": kind, "cycles": [cycles for _, cycles in runs]})
        say(
            f"  round {round_}: "
            + ", ".join(
                f"pair {'traced' if order[0] == 'rig_traced' else 'untraced'} first: untraced "
                f"{pair['rig'][0]:.0f}/s, traced {pair['rig_traced'][0]:.0f}/s "
                f"({ratio_of(pair['rig_traced'][0], pair['rig'][0]):.2f})"
                for pair, order in zip(pairs, orders, strict=True)
            )
            + "; "
            + ", ".join(f"{kind} {got[kind][0]:.0f}/s ({got[kind][1]} cycles)" for kind in got)
        )
    rpdos, tpdos = bench._floor_layout()
    return {
        "cycles": args.cycles,
        "rounds": args.rounds,
        "rig_pairs_per_round": RIG_PAIRS_PER_ROUND,
        "measured_cycles": measured,
        "budget_s": args.budget_s,
        **{f"{kind}_cycles_per_s": rates[kind] for kind in kinds},
        "frames_per_cycle": {
            "out": len(rpdos) + 1,
            "in": sum(1 / p.transmission_type for p in tpdos),
        },
    }


TIMED_BUS_RATES = {"ideal": None, "timed_carried": 2_000_000, "timed_overloaded": 1_000_000}
"""The Rig's lockstep cycle on the ideal bus and on the timed bus (`hilrig.engine.bustiming`):
at a bit rate that carries the default mapping's every frame at 1 kHz (2 Mbit/s: the steady
cycle's shortcut, what a mapping that fits costs) and at 1 Mbit/s, which it overloads (every
cycle scheduled frame by frame, frames waiting)."""
TIMED_BUS_ROUNDS = 4


def _timed_bus_runs(bench: BusBench, args: argparse.Namespace) -> dict[str, Any]:
    say(
        f"timed bus: {TIMED_BUS_ROUNDS} rounds of {args.cycles} cycles of the Rig untraced on the "
        "ideal bus, on a timed bus that carries its frames and on one they overload, alternating"
    )
    kinds = list(TIMED_BUS_RATES)
    rates: dict[str, list[float]] = {kind: [] for kind in kinds}
    for round_ in range(1, TIMED_BUS_ROUNDS + 1):
        order = kinds if round_ % 2 else kinds[::-1]
        got = {
            kind: bench.rig_rate(
                args.cycles, args.warmup, args.budget_s, traced=False, bitrate=TIMED_BUS_RATES[kind]
            )
            for kind in order
        }
        for kind in kinds:
            rates[kind].append(got[kind][0])
        say(
            f"  round {round_}: "
            + ", ".join(f"{kind} {got[kind][0]:.0f}/s ({got[kind][1]} cycles)" for kind in kinds)
        )
    return {
        "cycles": args.cycles,
        "rounds": TIMED_BUS_ROUNDS,
        "bitrates": TIMED_BUS_RATES,
        **{f"{kind}_cycles_per_s": rates[kind] for kind in kinds},
    }


def _robot_runs(bench: BusBench, args: argparse.Namespace) -> dict[str, Any]:
    say(
        f"robot: {ROBOT_SIZES} modules, {args.robot_cycles} gait cycles each, beside the raw "
        "N-node floor, two rounds alternating"
    )
    robot_rates: dict[str, list[float]] = {str(n): [] for n in ROBOT_SIZES}
    floor_rates: dict[str, list[float]] = {str(n): [] for n in ROBOT_SIZES}
    for round_ in range(2):
        for n in ROBOT_SIZES:
            # Robot and floor back to back, each first in one round: their ratio is the figure.
            order = ("robot", "floor") if round_ % 2 == 0 else ("floor", "robot")
            for kind in order:
                if kind == "robot":
                    rate, done = bench.robot_rate(n, args.robot_cycles, args.budget_s)
                    robot_rates[str(n)].append(rate)
                else:
                    rate, done = bench.robot_floor_rate(n, args.robot_cycles, args.budget_s)
                    floor_rates[str(n)].append(rate)
                say(f"  {n} modules, {kind}: {rate:.0f} cycles/s ({done} cycles)")
    return {"cycles": args.robot_cycles, "cycles_per_s": robot_rates, "floor_cycles_per_s": floor_rates}


def _long_trace_run(bench: BusBench, args: argparse.Namespace) -> dict[str, Any] | None:
    """None (no long run) with --long-trace-cycles 0."""
    if args.long_trace_cycles <= 0:
        return None
    say(f"long run: {args.long_trace_cycles} traced lockstep cycles of the Rig, its trace kept")
    run = bench.long_trace(args.long_trace_cycles)
    per_s = run["cycles"] / run["seconds"]
    say(f"  {run['trace']}: {run['bytes'] / 1e6:.1f} MB, {per_s:.0f} cycles/s")
    return run


def _sdo_runs(bench: BusBench, args: argparse.Namespace) -> dict[str, Any]:
    say(f"SDO: {args.sdo} expedited uploads each from the firmware and a canopen.LocalNode, alternating")
    return bench.sdo_latency(args.sdo, 2 * args.budget_s)


def _recorder_upload_runs(bench: BusBench, args: argparse.Namespace) -> dict[str, Any]:
    say("SDO: the recorder's whole buffer by block and by segmented upload, alternating")
    return bench.recorder_upload(3, 4 * args.budget_s)


def _free_running_run(bench: BusBench, args: argparse.Namespace) -> dict[str, Any]:
    say(f"free-running: {args.free_cycles} cycles of the firmware in --mode free")
    return bench.free_running(args.free_cycles)


def bus_main(args: argparse.Namespace) -> int:
    from hilrig.apps.busload import STANDARD_BITRATES, bus_load, lockstep_traffic
    from hilrig.errors import BusUnavailableError
    from hilrig.session.netns import PrivateBus, require_private_buses

    out: Path = args.out
    try:
        require_private_buses("bench: the bus part", "run it through tools/with-vcan")
    except BusUnavailableError as error:
        print(error, file=sys.stderr)
        return 1
    bus_path = os.environ.get("HIL_BUS_PATH", "unknown")
    result: dict[str, Any] = {"bus_path": bus_path, "bus_machine": machine()}
    not_measured = NotMeasured()
    with PrivateBus() as private_bus:
        bench = BusBench(private_bus, out)
        measurements: dict[str, Callable[[], Any]] = {
            "lockstep": lambda: _lockstep_runs(bench, args),
            "timed_bus": lambda: _timed_bus_runs(bench, args),
            "robot": lambda: _robot_runs(bench, args),
            "long_trace": lambda: _long_trace_run(bench, args),
            "sdo": lambda: _sdo_runs(bench, args),
            "recorder_upload": lambda: _recorder_upload_runs(bench, args),
            "free_running": lambda: _free_running_run(bench, args),
        }
        assert tuple(measurements) == BUS_MEASUREMENTS
        for name, measure in measurements.items():
            if args.only and name not in args.only:
                continue
            measured = not_measured.attempt(name, measure)
            if measured is not None:
                result[name] = measured
        proto, rate_hz = bench.proto, 1e6 / bench.period_us
    result["not_measured"] = not_measured
    traffic = lockstep_traffic(proto, rate_hz)
    result["bus_load"] = {
        "rate_hz": rate_hz,
        "frames_per_cycle": sum(t.per_second for t in traffic) / rate_hz,
        "loads": [
            {
                "bitrate": load.bitrate,
                "nominal": load.nominal,
                "worst_case": load.worst_case,
                "busiest_cycle": load.peak_cycle_worst_case,
            }
            for load in (bus_load(traffic, rate_hz, b) for b in STANDARD_BITRATES)
        ],
    }
    write_json_atomically(out / "bus.json", result)
    return 0
