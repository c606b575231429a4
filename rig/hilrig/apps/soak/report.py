"""The soak's report: the run's outcome and verdicts as JSON (`build_report`, written atomically
to OUT/report.json at the end and every minute while running), the progress line, and the
summary printed at the end.
"""

from __future__ import annotations

import argparse
import datetime
import enum
import json
import math
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

from hilrig.apps.soak.checker import Tally
from hilrig.apps.soak.fault_plan import FaultPlan
from hilrig.apps.soak.memory import memory_verdict
from hilrig.apps.soak.soak import Soak, SoakProgress
from hilrig.files import replacing

SERIES_POINTS = 250
"""The report keeps at most this many RSS samples (evenly thinned); the summary uses all."""


class RunStatus(enum.StrEnum):
    PASSED = "passed"
    FAILED = "failed"
    INTERRUPTED = "interrupted"
    RUNNING = "running"



def thin(items: Sequence[Any], points: int) -> list[Any]:
    """At most `points` items, evenly spread, first and last always kept."""
    if len(items) <= points:
        return list(items)
    step = (len(items) - 1) / (points - 1)
    return [items[round(i * step)] for i in range(points)]



def compare_counters(expected: dict[str, int], actual: dict[str, int]) -> list[str]:
    """'firmware: frames received 9001, expected 9002' for every counter that disagrees."""
    mismatches = []
    for name, value in expected.items():
        if name not in actual:
            mismatches.append(f"firmware stop line has no '{name}' counter")
        elif actual[name] != value:
            mismatches.append(f"firmware: {name} {actual[name]}, expected {value}")
    return mismatches



def write_json_atomic(path: Path, data: dict[str, Any]) -> None:
    """Write `data` as JSON to `path` via a temporary file and rename: never half a file."""
    with replacing(path) as temporary:
        temporary.write_text(json.dumps(data, indent=2) + "\n")


def format_duration(seconds: float) -> str:
    seconds = max(0, round(seconds))
    hours, rest = divmod(seconds, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours} h {minutes:02d} min" if hours else f"{minutes} min {secs:02d} s"


def format_progress(p: SoakProgress) -> str:
    left = (p.cycles - p.cycle) / p.recent_rate if p.recent_rate > 0 else float("inf")
    eta = format_duration(left) if math.isfinite(left) else "?"
    memory = f"; RSS {p.sample.vm_rss_kib} KiB, fds {p.sample.fds}" if p.sample is not None else ""
    return (
        f"soak: {p.cycle}/{p.cycles} cycles ({100 * p.cycle / max(p.cycles, 1):.1f} %), "
        f"{p.recent_rate:.0f} cycles/s (mean {p.rate:.0f}), ETA {eta}{memory}; "
        f"faults {p.faults}, lost {p.lost}, problems {p.problems}"
    )



def build_report(
    *,
    args: argparse.Namespace,
    soak: Soak | None,
    plan: FaultPlan,
    status: RunStatus,
    error: str | None,
    firmware: dict[str, Any],
    bus: dict[str, Any],
    started_wall: float,
    duration_s: float,
    driver_cpu_s: float,
    cycling_s: float | None = None,
) -> dict[str, Any]:
    """The soak report (JSON-ready). `status` is the run's outcome before the verdicts;
    `driver_cpu_s` is the CPU time of the soak's own process (the rig side)."""
    samples = soak.samples if soak is not None else []
    verdict = memory_verdict(samples, plan.warmup_cycle, args.rss_bound_kib)
    checker = soak.checker if soak is not None else None
    tally = checker.tally if checker is not None else Tally()
    stop = firmware.get("counters")
    mismatches = compare_counters(tally.expected_counters(), stop) if stop is not None else []
    if stop is None and status is not RunStatus.RUNNING:
        mismatches = ["no stop line from the firmware (killed, or crashed?)"]
    lost = checker.lost if checker is not None else []
    problems = checker.problems if checker is not None else []
    problem_count = checker.problem_count if checker is not None else 0
    failures = []
    if lost:
        failures.append(f"{len(lost)} lost cycle(s)")
    if problem_count:
        failures.append(f"{problem_count} check(s) failed")
    if verdict.ok is False:
        failures.append("memory: " + verdict.reason)
    if mismatches and status is not RunStatus.RUNNING:
        failures.append("firmware counters disagree: " + "; ".join(mismatches))
    if error:
        failures.append(error)
    velocity_summary = _velocity_summary(soak, soak.velocity_samples if soak is not None else [])
    for part in ("first_tenth", "last_tenth"):
        for key, value in velocity_summary.get(part, {}).items():
            if key.endswith("_max_error_pct") and value > velocity_summary["goal_max_error_pct"]:
                failures.append(
                    f"velocity estimate: {key.removesuffix('_max_error_pct')} off by {value} % in the "
                    f"{part.replace('_', ' ')}, goal below {velocity_summary['goal_max_error_pct']} %"
                )
    final = status
    if status is not RunStatus.RUNNING:
        if failures:
            final = RunStatus.FAILED
        elif status is RunStatus.INTERRUPTED:
            final = RunStatus.INTERRUPTED
        else:
            final = RunStatus.PASSED
    cycles = soak.cycle if soak is not None else 0
    fw_cpu = [s.cpu_s for s in samples]
    return {
        "status": final.value,
        "failures": failures,
        "cycles_requested": args.cycles,
        "cycles": cycles,
        "lost_cycles": len(lost),
        "lost": [asdict(c) for c in lost[:20]],
        "problems": problem_count,
        "problem_details": problems[:50],
        "faults": {
            "injected_by_kind": dict(soak.faults_done) if soak is not None else {},
            "injected": sum(soak.faults_done.values()) if soak is not None else 0,
            "planned": len(plan.faults),
            "interval": plan.interval,
            "seed": plan.seed,
        },
        "syncs": {
            "operational": tally.syncs_operational,
            "while_stopped": tally.syncs_stopped,
        },
        "frames_filtered": tally.frames_filtered,
        "memory": {
            **asdict(verdict),
            "samples": len(samples),
            "sample_every": args.sample_every,
            "series": [
                [s.cycle, s.vm_rss_kib, s.rss_exact_kib, s.anon_huge_kib, s.fds]
                for s in thin(samples, SERIES_POINTS)
            ],
            "series_columns": ["cycle", "VmRSS KiB", "exact Rss KiB", "AnonHugePages KiB", "fds"],
            "transparent_huge_pages": args.thp,
        },
        "firmware": {
            **firmware,
            "expected_counters": tally.expected_counters(),
            "mismatches": mismatches,
            "cpu_ms_per_cycle": round(1e3 * (fw_cpu[-1] - fw_cpu[0]) / cycles, 4)
            if len(fw_cpu) >= 2 and cycles
            else None,
        },
        "driver": {
            "cpu_ms_per_cycle": round(1e3 * driver_cpu_s / cycles, 4) if cycles else None,
            "pinned_cpu": args.cpu if args.pin else None,
            "heartbeats": tally.heartbeats,
            "heartbeat_states": {
                f"0x{state:02X}": n
                for state, n in sorted((checker.heartbeat_states if checker else {}).items())
            },
            "emcy": [
                f"cycle {c}: 0x{code:04X} about 0x{about:04X}"
                for c, code, about in (checker.emcy_log if checker else [])
            ][:300],
        },
        "velocity": velocity_summary,
        "duration_s": round(duration_s, 1),
        "cycling_s": round(cycling_s, 1) if cycling_s is not None else None,
        "rate_cycles_per_s": round(cycles / cycling_s, 1) if cycling_s else None,
        "started_at": datetime.datetime.fromtimestamp(started_wall, datetime.UTC).isoformat(
            timespec="seconds"
        ),
        "bus": bus,
        "seed": plan.seed,
        "period_us": args.period_us,
    }


def _velocity_summary(soak: Soak | None, samples: list[tuple[int, float, float]]) -> dict[str, Any]:
    """The firmware's velocity estimates against the pattern's exact speeds, in the first and the
    last tenth of the run (issue: numbers that stay right after hours): max error in percent."""
    if soak is None or not samples:
        return {}
    expected = {"motor": soak.pattern.motor_velocity_rad_s, "output": soak.pattern.output_velocity_rad_s}

    def spread(part: list[tuple[int, float, float]]) -> dict[str, float]:
        summary: dict[str, float] = {}
        for position, what in ((1, "motor"), (2, "output")):
            values = [row[position] for row in part if math.isfinite(row[position])]
            if not values:
                continue
            truth = expected[what]
            summary |= {
                f"{what}_min": round(min(values), 6),
                f"{what}_max": round(max(values), 6),
                f"{what}_max_error_pct": round(100 * max(abs(v - truth) for v in values) / truth, 6),
            }
        return summary

    tenth = max(1, len(samples) // 10)
    return {
        "expected_motor_velocity_rad_s": round(expected["motor"], 6),
        "expected_output_velocity_rad_s": round(expected["output"], 6),
        "first_tenth": spread(samples[:tenth]),
        "last_tenth": spread(samples[-tenth:]),
        "samples": len(samples),
        "goal_max_error_pct": 0.1,
    }


def print_summary(data: dict[str, Any], path: Path) -> None:
    memory = data["memory"]
    faults = data["faults"]
    kinds = ", ".join(f"{k} {v}" for k, v in sorted(faults["injected_by_kind"].items())) or "none"
    lines = [
        f"soak: {data['status'].upper()}: {data['cycles']} cycles in {format_duration(data['duration_s'])} "
        f"({data['rate_cycles_per_s']} cycles/s), lost {data['lost_cycles']}, problems {data['problems']}",
        f"soak: faults {faults['injected']} ({kinds})",
        f"soak: memory: {memory['reason']}"
        + (
            f"; RSS at start {memory['rss_start_kib']} KiB" if memory.get("rss_start_kib") is not None else ""
        ),
        f"soak: firmware: {data['firmware']['stop_line'] or 'no stop line'}",
        "soak: velocity estimate, max error in the first / last tenth: "
        + ", ".join(
            f"{what} {data['velocity'].get('first_tenth', {}).get(f'{what}_max_error_pct')} % / "
            f"{data['velocity'].get('last_tenth', {}).get(f'{what}_max_error_pct')} %"
            for what in ("motor", "output")
        ),
        f"soak: bus: {data['bus'].get('path')} (namespace {data['bus'].get('namespace')})",
    ]
    lines += [f"soak: FAILED: {failure}" for failure in data["failures"]]
    lines += [f"soak:   {detail}" for detail in data["problem_details"][:10]]
    lines.append(f"soak: report {path}")
    print("\n".join(lines), flush=True)
