"""`tools/bench.py report`: one table from native.json and bus.json, printed and written to
report.json atomically. Each row is a measure, ours, its baseline, their ratio and the goal; a
measurement that failed, or whose data cannot be read, is a row "not measured" with its error,
and every other row is still there. Here on the host, where Chromium is, it also times the web
viewer's first drawn frame of the bus step's long trace.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime
import json
import statistics
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from hilrig.apps.bench.baseline import MODES as BASELINE_MODES
from hilrig.apps.bench.baseline import baseline_rows, measure_baseline, remove_baseline
from hilrig.apps.bench.common import (
    LONG_TRACE_CYCLES,
    NOT_MEASURED,
    NotMeasured,
    bench_period_us,
    failure_text,
    machine,
    rate_text,
    ratio_of,
    say,
    write_json_atomically,
)
from hilrig.apps.bench.cycles import cycle_budget_rows
from hilrig.apps.bench.native import TRACE_PROBE_CYCLES, cycle_costs, rig_probe_per_cycle
from hilrig.apps.bench.size import size_rows
from hilrig.apps.bench.virt import virt_rows

LONG_TRACE_DASHBOARD = "overview"


CANOPENNODE_BLOCK_UPLOAD_KIB_PER_S = 100_000 / 1024 / 0.145
"""CANopenNode's own published figure for block upload on vcan: 100 kB in 145 ms (its README),
natively; shown beside ours, which the micro-VM's software emulation slows."""


RECORDER_IDLE_GOAL = 10  # instructions per cycle: an idle recorder is a comparison
RECORDER_ARMED_SHARE_GOAL = 0.10  # of the demo joint's cycle, 8 channels armed


def _not_measured_row(row: Callable[..., None], what: str, errors: Sequence[str]) -> None:
    """A row for a measurement whose probe failed: the first line of its error in the table,
    every error whole in the row's data."""
    row(what, NOT_MEASURED, errors[0].splitlines()[0], None, error="\n".join(errors))


def _recorder_rows(
    row: Callable[..., None], ipc: dict[str, float], not_measured: dict[str, str] | None = None
) -> None:
    """The field recorder's cost per cycle: armed (8 channels) vs idle, and vs a demo cycle.
    A native.json of an older run has no recorder loops: no rows then; a loop whose probe
    failed: its rows 'not measured' with the error."""
    failed = [
        (not_measured or {})[f"callgrind {loop}"]
        for loop in ("recorder_armed", "recorder_idle", "demo")
        if f"callgrind {loop}" in (not_measured or {})
    ]
    if failed and not all(loop in ipc for loop in ("recorder_armed", "recorder_idle", "demo")):
        for what in (
            "instructions/cycle: recorder 8 channels armed vs idle",
            "instructions/cycle: recorder 8 channels armed vs demo joint",
        ):
            _not_measured_row(row, what, failed)
        return
    if "recorder_armed" not in ipc or "recorder_idle" not in ipc:
        return
    armed, idle, demo = ipc["recorder_armed"], ipc["recorder_idle"], ipc["demo"]
    row(
        "instructions/cycle: recorder 8 channels armed vs idle",
        f"{armed:.0f}",
        f"{idle:.0f}",
        ratio_of(armed, idle),
        f"idle <= {RECORDER_IDLE_GOAL}",
        idle <= RECORDER_IDLE_GOAL,
    )
    share = ratio_of(armed, demo)
    row(
        "instructions/cycle: recorder 8 channels armed vs demo joint",
        f"{armed:.0f}",
        f"{demo:.0f}",
        share,
        f"<= {RECORDER_ARMED_SHARE_GOAL:.0%}",
        share <= RECORDER_ARMED_SHARE_GOAL,
    )


def _rig_probe_rows(
    row: Callable[..., None], probe: dict[str, float] | None, not_measured: dict[str, str] | None = None
) -> None:
    """The Rig's own lockstep cycle, natively and deterministically (`tools/rig_probe.py`): its
    instructions against the engine's exchange alone, what tracing a run costs per cycle (every
    thread, close included) against it, and the bytes its history keeps per cycle. A native.json
    of an older run has none: no rows then. A probe that failed: its rows 'not measured', each
    with the error of the probe it needed."""
    errors = {
        name.removeprefix("rig_probe "): text
        for name, text in (not_measured or {}).items()
        if name.startswith("rig_probe ")
    }
    if not probe and not errors:
        return
    probe = probe or {}

    def failed(*needs: str) -> list[str]:
        return [errors[need] for need in needs if need in errors]

    what = "instructions/cycle (main thread): Rig lockstep cycle vs the engine's exchange alone"
    if errors_of := failed("rig", "engine"):
        _not_measured_row(row, what, errors_of)
    else:
        row(what, f"{probe['rig']:.0f}", f"{probe['engine']:.0f}", ratio_of(probe["rig"], probe["engine"]))
    what = "instructions/cycle (main thread): Rig cycle with the joint's FMU (FMPy) vs its native plant"
    if "fmu" in errors:
        _not_measured_row(row, what, failed("fmu", "rig"))
    elif "fmu" in probe and "rig" in probe:  # a native.json from before the FMU probe has none
        row(what, f"{probe['fmu']:.0f}", f"{probe['rig']:.0f}", ratio_of(probe["fmu"], probe["rig"]))
    what = f"instructions/cycle (all threads): tracing a {TRACE_PROBE_CYCLES}-cycle run vs the Rig's cycle"
    if errors_of := failed("tracing", "rig"):
        _not_measured_row(row, what, errors_of)
    elif "tracing" in probe:  # a native.json from before the traced probe has none
        row(what, f"{probe['tracing']:.0f}", f"{probe['rig']:.0f}", ratio_of(probe["tracing"], probe["rig"]))
    what = "bytes per lockstep cycle: kept by the Rig (history) vs the data on the bus"
    if errors_of := failed("memory"):
        _not_measured_row(row, what, errors_of)
    else:
        row(
            what,
            f"{probe['kept_bytes']:.0f} B",
            f"{probe['bus_bytes']:.0f} B",
            ratio_of(probe["kept_bytes"], probe["bus_bytes"]),
        )


NO_LONG_TRACE = "no long run in bus.json (a bus step from before it, or --long-trace-cycles 0)"


def measure_first_frame(out: Path, long_trace: dict[str, Any] | None) -> dict[str, Any]:
    """The web viewer's time to a first drawn frame of the bus step's long trace, here on the
    host where Chromium is: {"seconds": ...} or, when it cannot be measured, {"error": why}."""
    if long_trace is None:
        return {"error": NO_LONG_TRACE}
    trace = out / long_trace["trace"]
    if not trace.is_file():
        return {"error": f"no trace at {trace}"}
    from hilrig.observe.browser import ViewerCheckError, browser_missing, time_to_first_frame

    missing = browser_missing()
    if missing is not None:
        return {"error": missing}
    screenshot = trace.parent / "first-frame.png"
    say(f"web viewer: time to the first drawn frame of {trace} ({LONG_TRACE_DASHBOARD})")
    try:
        seconds = time_to_first_frame(trace, LONG_TRACE_DASHBOARD, screenshot=screenshot)
    except ViewerCheckError as error:
        return {"error": str(error).splitlines()[0], "screenshot": str(screenshot)}
    say(f"  {seconds:.1f} s")
    return {"seconds": seconds, "dashboard": LONG_TRACE_DASHBOARD, "screenshot": str(screenshot)}


def _long_trace_rows(
    row: Callable[..., None], long_trace: dict[str, Any] | None, first_frame: dict[str, Any]
) -> None:
    """The long run's .rrd size and the web viewer's time to draw it; each row says why when
    it was not measured (no long run in bus.json, no Chromium, a viewer that never drew)."""
    period_us = long_trace.get("period_us", bench_period_us()) if long_trace else bench_period_us()
    rate = rate_text(period_us)
    if long_trace is None:
        size_what = f"{LONG_TRACE_CYCLES * period_us / 1e6:g} s run at {rate}"
        row(f".rrd size of a {size_what} (ratio: bytes per cycle)", "not measured", NO_LONG_TRACE, None)
    else:
        cycles, size = long_trace["cycles"], long_trace["bytes"]
        seconds_run = cycles * period_us / 1e6
        row(
            f".rrd size of a {seconds_run:g} s run at {rate} (ratio: bytes per cycle)",
            f"{size / 1e6:.1f} MB",
            f"{cycles} cycles",
            ratio_of(size, cycles),
            **long_trace,
        )
    what = "time to first drawn frame (web viewer, headless Chromium, software WebGL)"
    if "seconds" in first_frame:
        cycles_shown = f"{long_trace['cycles']} cycles" if long_trace else "the long trace"
        row(
            what,
            f"{first_frame['seconds']:.1f} s",
            f"{cycles_shown}, {first_frame['dashboard']}",
            None,
            **first_frame,
        )
    else:
        row(what, "not measured", first_frame["error"], None, **first_frame)


class ReportRows(list[dict[str, Any]]):
    """The report's rows; calling it adds one: measure, ours, baseline, ratio, goal, whether
    the goal is met, and the measurement's own data."""

    def __call__(
        self,
        what: str,
        ours: str,
        baseline: str,
        ratio: float | None,
        goal: str = "",
        met: bool | None = None,
        **data: Any,
    ) -> None:
        self.append(
            {
                "measure": what,
                "ours": ours,
                "baseline": baseline,
                "ratio": ratio,
                "goal": goal,
                "goal_met": met,
                "data": data,
            }
        )


def _lockstep_rows(row: ReportRows, bus: dict[str, Any]) -> None:
    """The Rig against its floors, traced against untraced, and simulated time."""
    lockstep = bus["lockstep"]
    kinds = ("rig", "rig_traced", "floor", "engine_floor", "python_can")
    best = {
        kind: max(lockstep[f"{kind}_cycles_per_s"]) for kind in kinds if f"{kind}_cycles_per_s" in lockstep
    }
    ratio = ratio_of(best["rig"], best["floor"])
    row(
        "lockstep cycles/s: Rig untraced vs raw-socket floor",
        f"{best['rig']:.0f}/s",
        f"{best['floor']:.0f}/s",
        ratio,
        ">= 0.5",
        ratio >= 0.5,
        **lockstep,
    )
    # Traced vs untraced, the goal: the median over the pairs of runs back to back. The host's speed
    # drifts between rounds, and the best of each kind compares each one's luckiest moment.
    untraced, traced = lockstep["rig_cycles_per_s"], lockstep["rig_traced_cycles_per_s"]
    best_ratio = ratio_of(best["rig_traced"], best["rig"])
    is_paired = len(untraced) == len(traced) > 1  # runs paired by their place in the lists
    if is_paired:
        paired = [ratio_of(t, u) for t, u in zip(traced, untraced, strict=True)]
        ratio = statistics.median(paired)
        row(
            "lockstep cycles/s: Rig traced vs untraced, median of the runs paired back to back",
            f"{min(paired):.2f}..{max(paired):.2f}",
            f"{len(paired)} pairs",
            ratio,
            ">= 0.8",
            ratio >= 0.8,
        )
    row(  # the goal only for a bus.json of runs not paired
        "lockstep cycles/s: Rig traced vs untraced, best of each",
        f"{best['rig_traced']:.0f}/s",
        f"{best['rig']:.0f}/s",
        best_ratio,
        *(() if is_paired else (">= 0.8", best_ratio >= 0.8)),
    )
    if "engine_floor" in best:  # a bus.json of before the engine's exchange floor lacks it
        row(
            "lockstep cycles/s: Rig untraced vs the engine's exchange alone (C, no physics/history)",
            f"{best['rig']:.0f}/s",
            f"{best['engine_floor']:.0f}/s",
            ratio_of(best["rig"], best["engine_floor"]),
        )
        row(
            "lockstep cycles/s: the engine's exchange alone vs raw-socket floor",
            f"{best['engine_floor']:.0f}/s",
            f"{best['floor']:.0f}/s",
            ratio_of(best["engine_floor"], best["floor"]),
        )
    row(
        "lockstep cycles/s: python-can floor vs raw-socket floor",
        f"{best['python_can']:.0f}/s",
        f"{best['floor']:.0f}/s",
        ratio_of(best["python_can"], best["floor"]),
    )
    period_s = bench_period_us() / 1e6
    for kind, label in (("rig", "Rig untraced"), ("rig_traced", "Rig traced")):
        row(
            f"simulated time vs real time at {rate_text(period_s * 1e6)} ({label})",
            f"{best[kind] * period_s:.2f}x",
            "1.00x (real time)",
            best[kind] * period_s,
        )


TIMED_BUS_GOAL = 1 / 1.10
"""The Rig's cycles/s on a timed bus that carries its frames against on the ideal bus: at most
10 % slower."""


def _timed_bus_rows(row: ReportRows, bus: dict[str, Any]) -> None:
    """The Rig on the timed bus (`hilrig.engine.bustiming`) beside the ideal bus: the median of
    the rounds' ratios (each round runs all three back to back)."""
    timed = bus.get("timed_bus")
    if not timed:
        return
    ideal = timed["ideal_cycles_per_s"]
    for kind, label, goal in (
        ("timed_carried", "a bit rate that carries every frame", True),
        ("timed_overloaded", "1 Mbit/s, which the default mapping overloads", False),
    ):
        rates = timed[f"{kind}_cycles_per_s"]
        ratio = statistics.median(ratio_of(t, i) for t, i in zip(rates, ideal, strict=True))
        row(
            f"lockstep cycles/s: Rig on the timed bus ({label}) vs the ideal bus, median of rounds",
            f"{max(rates):.0f}/s",
            f"{max(ideal):.0f}/s",
            ratio,
            f">= {TIMED_BUS_GOAL:.2f} (at most 10 % slower)" if goal else "",
            ratio >= TIMED_BUS_GOAL if goal else None,
            **({"timed_bus": timed} if goal else {}),
        )


ROBOT_FLOOR_GOAL = 0.5
"""Robot cycles/s against the raw N-node floor, for every N."""
ROBOT_PER_MODULE_GOAL = 1.2
"""A module's share of the cycle's cost at the largest robot against at one module."""


def _robot_rows(row: ReportRows, bus: dict[str, Any]) -> None:
    """How a robot's lockstep cycle grows with its modules, and how far it is from the raw
    N-node floor (the same frames with N firmware processes over one raw socket)."""
    robot = bus.get("robot")
    if not robot:
        return
    rates = {int(n): max(values) for n, values in robot["cycles_per_s"].items() if values}
    floors = {int(n): max(values) for n, values in robot.get("floor_cycles_per_s", {}).items() if values}
    one = rates.get(1)
    for n, rate in sorted(rates.items()):
        modules = f"{n} module{'s' if n > 1 else ''}"
        floor = floors.get(n)
        if floor is not None:
            ratio = ratio_of(rate, floor)
            row(
                f"robot lockstep cycles/s, {modules}: robot vs raw {n}-node floor",
                f"{rate:.0f}/s",
                f"{floor:.0f}/s",
                ratio,
                f">= {ROBOT_FLOOR_GOAL:g}",
                ratio >= ROBOT_FLOOR_GOAL,
                **({"floor_cycles_per_s": robot["floor_cycles_per_s"]} if n == 1 else {}),
            )
        # Cost per cycle relative to one module: how it grows with N (N: linear in the modules).
        growth = one / rate if one and rate else float("nan")
        per_module = growth / n
        largest = n == max(rates) and n > 1
        row(
            f"robot lockstep cycles/s, {modules} vs 1 (cycle cost ratio)",
            f"{rate:.0f}/s",
            f"{one:.0f}/s" if one else "-",
            growth,
            ""
            if n == 1
            else f"{per_module:.2f}x per module"
            + (f" (goal <= {ROBOT_PER_MODULE_GOAL:g})" if largest else ""),
            per_module <= ROBOT_PER_MODULE_GOAL if largest else None,
            **({"cycles": robot["cycles"], "cycles_per_s": robot["cycles_per_s"]} if n == 1 else {}),
        )
    if len(floors) > 1 and 1 in floors:
        n = max(floors)
        per_module = floors[1] / floors[n] / n
        row(
            f"raw N-node floor cycles/s, {n} modules vs 1 (cost per module)",
            f"{floors[n]:.0f}/s",
            f"{floors[1]:.0f}/s",
            per_module,
            "what the bus and the firmware alone allow",
            None,
        )


def _recorder_upload_rows(row: ReportRows, bus: dict[str, Any]) -> None:
    """The recorder's buffer by block against segmented SDO upload."""
    upload = bus.get("recorder_upload")
    if upload:
        block, segmented = max(upload["block_bytes_per_s"]), max(upload["segmented_bytes_per_s"])
        ratio = ratio_of(block, segmented)
        row(
            f"SDO upload of the recorder's {upload['bytes'] / 1024:.0f} KiB: block vs segmented",
            f"{block / 1024:.0f} KiB/s",
            f"{segmented / 1024:.0f} KiB/s",
            ratio,
            ">= 5x",
            ratio >= 5.0,
            canopennode_published_vcan_kib_per_s=CANOPENNODE_BLOCK_UPLOAD_KIB_PER_S,
            **upload,
        )


def _sdo_rows(row: ReportRows, bus: dict[str, Any]) -> None:
    """SDO latency and turnaround, the firmware against a canopen.LocalNode."""
    sdo = bus["sdo"]
    ours_us, local_us = sdo["firmware"]["median_us"], sdo["local_node"]["median_us"]
    ratio = ratio_of(local_us, ours_us)
    row(
        "SDO upload median (firmware vs LocalNode)",
        f"{ours_us:.0f} us",
        f"{local_us:.0f} us",
        ratio,
        ">= 3x faster",
        ratio >= 3.0,
        **sdo,
    )
    served = sdo.get("turnaround_median_us") or {}
    if served.get("firmware") and served.get("local_node"):
        row(
            "SDO server turnaround median (kernel timestamps)",
            f"{served['firmware']:.0f} us",
            f"{served['local_node']:.0f} us",
            ratio_of(served["local_node"], served["firmware"]),
        )


def _board_bench_rows(row: ReportRows, native: dict[str, Any], not_measured: dict[str, str]) -> None:
    """fw_board_bench's ratios; a failed run's rows say why."""
    ns = native["board_bench_ns"]
    failed = not_measured.get("board_bench")
    for what, ours, base, base_name in (
        ("board get (vs raw array)", "BM_Get_MessageBoard", "BM_Get_RawArray", "raw"),
        ("board get (vs unordered_map<string>)", "BM_Get_MessageBoard", "BM_Get_StringMap", "map"),
        ("board set (vs raw array)", "BM_Set_MessageBoard", "BM_Set_RawArray", "raw"),
        ("board set (vs unordered_map<string>)", "BM_Set_MessageBoard", "BM_Set_StringMap", "map"),
        ("17-component cycle (vs naive board)", "BM_Cycle_MessageBoard", "BM_Cycle_StringMap", "map"),
    ):
        if failed and not (ours in ns and base in ns):
            _not_measured_row(row, what, [failed])
        elif ours in ns and base in ns:
            r = ratio_of(ns[ours], ns[base])
            goal, met = "", None
            if ours == "BM_Get_MessageBoard" and base_name == "raw":
                goal, met = "<= 2x", r <= 2.0
            if ours == "BM_Cycle_MessageBoard":
                goal, met = "< 2000 ns", ns[ours] < 2000
            row(what, f"{ns[ours]:.2f} ns", f"{ns[base]:.2f} ns", r, goal, met)


def _instruction_rows(row: ReportRows, native: dict[str, Any], not_measured: dict[str, str]) -> None:
    """Instructions of one control cycle under callgrind (fw_cycle_count): a pair whose loop
    failed is a row 'not measured' with the loop's error."""
    callgrind = native.get("callgrind")
    if not callgrind:
        return
    ipc = callgrind["instructions_per_cycle"]
    for what, ours, base, data in (
        ("instructions/cycle: demo joint vs stand-ins on naive board", "demo", "naive", callgrind),
        ("instructions/cycle: stand-ins, core vs naive board", "core", "naive", {}),
    ):
        failed = [
            not_measured[f"callgrind {loop}"] for loop in (ours, base) if f"callgrind {loop}" in not_measured
        ]
        if failed:
            _not_measured_row(row, what, failed)
        else:
            row(what, f"{ipc[ours]:.0f}", f"{ipc[base]:.0f}", ratio_of(ipc[ours], ipc[base]), **data)
    _recorder_rows(row, ipc, not_measured)


def _bus_load_rows(row: ReportRows, bus: dict[str, Any]) -> None:
    """The bus load of the default PDO mapping at the bench's rate."""
    load = bus["bus_load"]
    rate = rate_text(1e6 / load["rate_hz"] if "rate_hz" in load else bench_period_us())
    for item in load["loads"]:
        mbit = item["bitrate"] / 1e6
        label = f"{mbit:g} Mbit/s" if mbit >= 1 else f"{item['bitrate'] // 1000} kbit/s"
        row(
            f"bus load at {rate}, {label} (worst-case stuffing)",
            f"{100 * item['worst_case']:.1f} %",
            f"{100 * item['nominal']:.1f} % nominal",
            item["worst_case"],
            "<= 70 %",
            item["worst_case"] <= 0.7,
            busiest_cycle=item["busiest_cycle"],
            frames_per_cycle=load["frames_per_cycle"],
        )


def _free_running_rows(row: ReportRows, bus: dict[str, Any], bus_path: str) -> None:
    """The free-running firmware's period error."""
    free = bus["free_running"]
    err = free["abs_error_us"]
    vm = not bus_path.startswith("native")
    row(
        "free-running |period error| p50 / p99 / max",
        f"{err['50']:.0f} / {err['99']:.0f} / {err['max']:.0f} us",
        f"period {free['period_us']} us",
        err["99"] / free["period_us"],
        "not meaningful: software-emulated VM" if vm else "",
        None,
        **free,
    )


SECTION_TITLES = {
    "lockstep": "lockstep cycles/s (Rig, traced, floors)",
    "timed_bus": "lockstep cycles/s on the timed bus vs the ideal bus",
    "robot": "robot lockstep cycles/s",
    "recorder_upload": "SDO upload of the recorder's buffer: block vs segmented",
    "sdo": "SDO upload median (firmware vs LocalNode)",
    "board_bench": "board get/set and cycle (fw_board_bench)",
    "cortex_m_size": "Cortex-M4F firmware image: flash and RAM vs budget",
    "cortex_m_cycles": "Cortex-M4F worst control cycle vs its budget",
    "virt": "bare-metal image (qemu-virt): flash, RAM, instructions/cycle",
    "callgrind": "instructions/cycle (callgrind)",
    "rig_probe": "the Rig's own lockstep cycle (tools/rig_probe.py)",
    "baseline": "the engine's instructions/cycle, this checkout vs a baseline commit",
    "long_trace": "long traced run",
    "bus_load": "bus load at 1 kHz",
    "free_running": "free-running |period error|",
}
"""The report's sections, in order; a section whose data is missing or broken is one row
'not measured' under this title, with the error."""


def build_report(
    native: dict[str, Any], bus: dict[str, Any], bus_path: str, first_frame: dict[str, Any]
) -> dict[str, Any]:
    """The report's rows from the native and bus parts' JSON and the web viewer's time to a
    first frame of the long trace (`measure_first_frame`). A measurement that failed (its
    error in the part's "not_measured") or whose data cannot be read is a row 'not measured'
    with its error text; every other row is still there."""
    rows = ReportRows()
    not_measured: dict[str, str] = {**native.get("not_measured", {}), **bus.get("not_measured", {})}
    sections: dict[str, Callable[[], None]] = {
        "lockstep": lambda: _lockstep_rows(rows, bus),
        "timed_bus": lambda: _timed_bus_rows(rows, bus),
        "robot": lambda: _robot_rows(rows, bus),
        "recorder_upload": lambda: _recorder_upload_rows(rows, bus),
        "sdo": lambda: _sdo_rows(rows, bus),
        "board_bench": lambda: _board_bench_rows(rows, native, not_measured),
        "cortex_m_size": lambda: size_rows(rows, native["cortex_m_size"]),
        "cortex_m_cycles": lambda: cycle_budget_rows(rows, native["cortex_m_cycles"]),
        "virt": lambda: virt_rows(rows, native),
        "callgrind": lambda: _instruction_rows(rows, native, not_measured),
        "rig_probe": lambda: _rig_probe_rows(rows, native.get("rig_probe"), not_measured),
        "baseline": lambda: baseline_rows(
            rows, native.get("rig_probe"), native.get("baseline"), not_measured
        ),
        "long_trace": lambda: _long_trace_rows(rows, bus.get("long_trace"), first_frame),
        "bus_load": lambda: _bus_load_rows(rows, bus),
        "free_running": lambda: _free_running_rows(rows, bus, bus_path),
    }
    for name, add_rows in sections.items():
        kept = len(rows)
        try:
            add_rows()
        except Exception as error:  # its data is missing or unreadable: this section only
            del rows[kept:]
            text = not_measured.get(name) or failure_text(error)
            rows(SECTION_TITLES[name], NOT_MEASURED, text.splitlines()[0], None, error=text)
    return {
        "date": native["date"],
        "machine": native["machine"],
        "bus_path": bus_path,
        "bus_machine": bus.get("bus_machine"),
        "rows": rows,
    }


def format_report(report: dict[str, Any]) -> str:
    m = report["machine"]
    lines = [
        f"make bench report  {report['date']}",
        f"machine: {m['cpu']}, {m['cores']} cores, kernel {m['kernel']}",
        f"bus path: {report['bus_path']}",
        "",
    ]
    lines += format_table(report["rows"])
    lines += [
        "",
        "ratios: lockstep = ours/baseline rate and SDO = LocalNode/firmware latency (higher is better);",
        "        board and instructions = ours/baseline (lower is better); free-running = p99 error/period;",
        "        .rrd size = bytes per cycle.",
    ]
    free = next((r["data"] for r in report["rows"] if r["measure"].startswith("free-running")), {})
    if "method" in free:
        lines += [
            f"free-running: {free['method']};",
            f"        {free['cycles']} periods, mean {free['mean_period_us']:.1f} us, "
            f"{free['late_by_half_a_period']} late by > half a period, "
            f"firmware overruns {free['firmware_overruns']}.",
        ]
    if not report["bus_path"].startswith("native"):
        lines.append(
            "free-running timing was measured inside the software-emulated micro-VM: its timers and "
            "scheduling say nothing about a real target, so that row is NOT meaningful here."
        )
    return "\n".join(lines + format_errors(report["rows"]))


def format_table(rows: Sequence[dict[str, Any]]) -> list[str]:
    """The rows as a table's lines: measure, ours, baseline, ratio, and the goal, met or MISSED."""
    header = ["measure", "ours", "baseline", "ratio", "goal"]
    table = [header]
    for r in rows:
        goal = r["goal"]
        if r["goal_met"] is not None:
            goal = f"{goal}: {'met' if r['goal_met'] else 'MISSED'}"
        ratio = "" if r["ratio"] is None else f"{r['ratio']:.3g}"
        table.append([r["measure"], r["ours"], r["baseline"], ratio, goal])
    widths = [max(len(row[i]) for row in table) for i in range(len(header))]
    lines = []
    for n, row in enumerate(table):
        lines.append("  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)).rstrip())
        if n == 0:
            lines.append("  ".join("-" * w for w in widths))
    return lines


def format_errors(rows: Sequence[dict[str, Any]]) -> list[str]:
    """The whole error of each row not measured whose error has more than one line (a failed
    probe's stderr tail), to print after the table."""
    lines = []
    for r in rows:
        if r["ours"] == NOT_MEASURED and "\n" in r["data"].get("error", ""):
            lines += [
                "",
                f"{NOT_MEASURED}: {r['measure']}:",
                *(f"    {line}" for line in r["data"]["error"].splitlines()),
            ]
    return lines


NATIVE_SECTIONS = ("board_bench", "cortex_m_size", "cortex_m_cycles", "callgrind", "rig_probe", "baseline")


def _read_part(path: Path, step: str, sections: Sequence[str]) -> tuple[dict[str, Any], bool]:
    """(the part's JSON, True), or, when the step wrote none, (a part whose every section is
    not measured, saying so, False): the report is written from what there is."""
    try:
        return json.loads(path.read_text()), True
    except (OSError, ValueError) as error:
        why = f"{path.name} is unreadable ({error}): the {step} step did not finish"
        print(f"bench: {why}", file=sys.stderr)
        return {"not_measured": dict.fromkeys(sections, why)}, False


def report_main(args: argparse.Namespace) -> int:
    out: Path = args.out
    native, native_whole = _read_part(out / "native.json", "native", NATIVE_SECTIONS)
    bus_sections = [name for name in SECTION_TITLES if name not in NATIVE_SECTIONS]
    bus, bus_whole = _read_part(out / "bus.json", "bus", bus_sections)
    native.setdefault("date", datetime.datetime.now().astimezone().isoformat())
    native.setdefault("machine", machine())
    bus_path = bus.get("bus_path", "unknown")
    with contextlib.suppress(OSError):
        bus_path = (out / "bus-path.txt").read_text().strip() or bus_path
    report = build_report(native, bus, bus_path, measure_first_frame(out, bus.get("long_trace")))
    print(format_report(report))
    write_json_atomically(out / "report.json", report)
    say(f"report written to {out / 'report.json'}")
    return 0 if native_whole and bus_whole else 1


def baseline_main(args: argparse.Namespace) -> int:
    """`tools/bench.py baseline`: the engine comparison alone, natively (no firmware build, no
    bus): the checkout's and the baseline commit's `tools/rig_probe.py rig` and `engine` under
    callgrind, their rows printed and written with the figures to <out>/baseline.json (never to
    native.json, which holds a whole native step). Exit 1 when a figure is not measured.
    With --remove: the exported baseline trees removed instead."""
    out: Path = args.out
    if args.remove:
        remove_baseline(out)
        return 0
    not_measured = NotMeasured()
    say("the checkout's engine (tools/rig_probe.py under callgrind)")
    probe = cycle_costs(not_measured)
    baseline = measure_baseline(out, args.baseline, not_measured, rig_probe_per_cycle)
    rows = ReportRows()
    baseline_rows(rows, probe, baseline, not_measured)
    print("\n".join(format_table(rows) + format_errors(rows)))
    result = {
        "date": datetime.datetime.now().astimezone().isoformat(),
        "machine": machine(),
        "rig_probe": probe,
        "baseline": baseline,
        "not_measured": not_measured,
        "rows": rows,
    }
    write_json_atomically(out / "baseline.json", result)
    say(f"written to {out / 'baseline.json'}")
    measured = all(mode in probe and mode in baseline for mode in BASELINE_MODES)
    return 0 if measured else 1
