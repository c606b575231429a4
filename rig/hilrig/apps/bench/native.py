"""`tools/bench.py native`: the C++ parts and the Rig's own cycle, natively. fw_board_bench
(Google Benchmark), the instructions of one control cycle under callgrind (`fw_cycle_count`: the
demo joint, the stand-ins on the core and the naive board, the field recorder idle and armed),
and `tools/rig_probe.py` under callgrind and tracemalloc, the checkout's beside a baseline
commit's (`baseline`). Writes <out>/native.json; a probe that fails leaves its error under
"not_measured".
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import re
import shutil
import sys
import tempfile
from pathlib import Path
from typing import Any

from hilrig.apps.bench.baseline import measure_baseline, prepare_checkout
from hilrig.apps.bench.common import (
    ROOT,
    NotMeasured,
    ProbeError,
    machine,
    run_probe,
    say,
    write_json_atomically,
)
from hilrig.apps.bench.cycles import cycle_budget
from hilrig.apps.bench.size import image_size
from hilrig.apps.bench.virt import virt_cycle_cost, virt_size

CALLGRIND_CYCLES = 2000
# fw_cycle_count's loops: the demo joint, the stand-ins on the core and on the naive board, and
# the field recorder's end-of-cycle call idle and armed with 8 channels.
CALLGRIND_LOOPS = ("demo", "core", "naive", "recorder_idle", "recorder_armed")


def run_board_bench(out: Path) -> dict[str, float]:
    """Runs fw_board_bench (its console output shown as it goes); ns per iteration by name."""
    json_path = out / "fw_board_bench.json"
    json_path.unlink(missing_ok=True)
    exe = out / "bin" / "fw_board_bench"
    run_probe([str(exe), f"--benchmark_out={json_path}", "--benchmark_out_format=json"], show_stdout=True)
    scale = {"ns": 1.0, "us": 1e3, "ms": 1e6, "s": 1e9}
    data = json.loads(json_path.read_text())
    return {
        b["name"]: b["real_time"] * scale[b["time_unit"]]
        for b in data["benchmarks"]
        if b.get("run_type", "iteration") == "iteration" and not b.get("error_occurred")
    }


def _callgrind_total(
    options: list[str], command: list[str], *, python: bool = False, all_threads: bool = False
) -> int:
    """Instructions callgrind counted running `command` with `options`; for a `python` command
    those of its main thread alone (its threads counted apart) unless `all_threads`, with the
    same string hashes every run (so the same dict layouts) and numpy's BLAS on the calling
    thread (its worker threads spin after a call, and callgrind would count their spinning,
    which moves the totals of the same run)."""
    with tempfile.TemporaryDirectory(prefix="bench-callgrind-") as folder:
        data = Path(folder) / "callgrind.out"
        main_thread = python and not all_threads
        threads = ["--separate-threads=yes"] if main_thread else []
        run_probe(
            ["valgrind", "--tool=callgrind", *threads, *options, f"--callgrind-out-file={data}", *command],
            env={**os.environ, "PYTHONHASHSEED": "0", "OPENBLAS_NUM_THREADS": "1"} if python else None,
        )
        written = Path(f"{data}-01") if main_thread else data
        match = re.search(r"^(?:summary|totals):\s*(\d+)", written.read_text(), re.MULTILINE)
        if match is None:
            raise RuntimeError(f"no instruction total in callgrind output of {' '.join(command)}")
        return int(match.group(1))


def callgrind_instructions(out: Path, loop: str, cycles: int) -> int:
    """Instructions inside hil_count_<loop> (fw_cycle_count) for `cycles` cycles."""
    options = ["--collect-atstart=no", f"--toggle-collect=hil_count_{loop}"]
    return _callgrind_total(options, [str(out / "bin" / "fw_cycle_count"), loop, str(cycles)])


RIG_PROBE_CYCLES = (500, 2500)
"""`tools/rig_probe.py` runs at two lengths: their difference is what the cycles cost."""


TRACE_PROBE_CYCLES = 2000
"""Cycles of the traced run `tools/rig_probe.py` measures: as many as a `make bench` round's."""


def rig_probe_instructions(mode: str, cycles: int, *, all_threads: bool = False, root: Path = ROOT) -> int:
    """Instructions of the main thread (or of all threads) of `tools/rig_probe.py MODE CYCLES`
    under callgrind; the probe of the tree at `root` (the checkout, or a baseline's export)."""
    command = [sys.executable, str(root / "tools" / "rig_probe.py"), mode, str(cycles)]
    return _callgrind_total([], command, python=True, all_threads=all_threads)


def rig_probe_per_cycle(mode: str, root: Path = ROOT) -> float:
    """Instructions per cycle of `tools/rig_probe.py MODE` of the tree at `root`: the difference
    of two lengths, so start-up cancels out."""
    short, long = RIG_PROBE_CYCLES
    return (
        rig_probe_instructions(mode, long, root=root) - rig_probe_instructions(mode, short, root=root)
    ) / (long - short)


def _tracing_per_cycle() -> float:
    """Every thread of a traced run (the sender, Rerun's encoder and file writer, close() and the
    file's footer included) against the same run with the Tracer made but not attached."""
    traced, idle = (
        rig_probe_instructions(mode, TRACE_PROBE_CYCLES, all_threads=True)
        for mode in ("traced", "tracer-idle")
    )
    return (traced - idle) / TRACE_PROBE_CYCLES


def _rig_memory_per_cycle() -> tuple[float, float]:
    """(bytes the Rig keeps, data bytes the bus carried) per cycle."""
    probe = [sys.executable, str(ROOT / "tools" / "rig_probe.py"), "memory", str(RIG_PROBE_CYCLES[1])]
    printed = run_probe(probe)
    figures = re.findall(r"[\d.]+", printed)[:2]
    if len(figures) != 2:
        raise ProbeError(f"rig_probe.py memory: expected two figures, got {printed.strip()!r}")
    return float(figures[0]), float(figures[1])


def cycle_costs(not_measured: NotMeasured) -> dict[str, float]:
    """Instructions per cycle (callgrind) of the checkout's Rig lockstep cycle and of the
    engine's exchange alone, its probe checked first as a baseline's is (`prepare_checkout`).
    A probe that fails leaves its key out and its error in `not_measured`."""
    not_measured.attempt("rig_probe check", prepare_checkout)  # a failure shows in the counts too
    costs: dict[str, float] = {}
    for mode in ("rig", "engine"):
        cost = not_measured.attempt(f"rig_probe {mode}", lambda mode=mode: rig_probe_per_cycle(mode))
        if cost is not None:
            costs[mode] = cost
            say(f"  {mode}: {cost:.0f} instructions per cycle")
    return costs


def rig_probe_costs(not_measured: NotMeasured) -> dict[str, float]:
    """The Rig's lockstep cycle and the engine's exchange alone, natively (`tools/rig_probe.py`):
    instructions per cycle of each (callgrind, `cycle_costs`), of the Rig's cycle with the joint's
    FMU as its plant (build/fmu/joint.fmu), what tracing costs per cycle, and
    the Rig's bytes kept per cycle. A probe that fails leaves its key out and its error in
    `not_measured`."""
    costs = cycle_costs(not_measured)
    fmu = not_measured.attempt("rig_probe fmu", lambda: rig_probe_per_cycle("fmu"))
    if fmu is not None:
        costs["fmu"] = fmu
        say(f"  fmu (the joint's FMU as the plant): {fmu:.0f} instructions per cycle")
    tracing = not_measured.attempt("rig_probe tracing", _tracing_per_cycle)
    if tracing is not None:
        costs["tracing"] = tracing
        say(f"  tracing {TRACE_PROBE_CYCLES} cycles: {tracing:.0f} instructions per cycle (all threads)")
    memory = not_measured.attempt("rig_probe memory", _rig_memory_per_cycle)
    if memory is not None:
        costs["kept_bytes"], costs["bus_bytes"] = memory
        say(f"  the Rig keeps {memory[0]:.0f} bytes per cycle; the bus carried {memory[1]:.0f}")
    return costs


def native_main(args: argparse.Namespace) -> int:
    out: Path = args.out
    (out / "bus.json").unlink(missing_ok=True)  # parts of an earlier run are not mixed in
    result: dict[str, Any] = {"machine": machine(), "date": datetime.datetime.now().astimezone().isoformat()}
    not_measured = NotMeasured()
    say("firmware core benchmarks (fw_board_bench, Google Benchmark)")
    result["board_bench_ns"] = not_measured.attempt("board_bench", lambda: run_board_bench(out)) or {}
    say("size of the Cortex-M4F firmware image (build/cortex-m)")
    result["cortex_m_size"] = not_measured.attempt("cortex_m_size", image_size)
    say("worst control cycle of the Cortex-M4F firmware under qemu -icount (build/cortex-m)")
    result["cortex_m_cycles"] = not_measured.attempt("cortex_m_cycles", cycle_budget)
    say("the bare-metal image (build/qemu-virt): size, and its cycle under qemu -icount")
    result["virt_size"] = not_measured.attempt("virt_size", virt_size)
    result["virt_cycle"] = not_measured.attempt("virt_cycle", virt_cycle_cost)
    if shutil.which("valgrind") is None:
        say("valgrind is missing (apt-get install valgrind, or make deps): no instruction counts")
        result["callgrind"] = None
        not_measured["baseline"] = "valgrind is missing (apt-get install valgrind, or make deps)"
    else:
        say(f"instruction counts under callgrind ({CALLGRIND_CYCLES} cycles per loop, minus a 0-cycle run)")
        per_cycle = {}
        for loop in CALLGRIND_LOOPS:
            cost = not_measured.attempt(
                f"callgrind {loop}",
                lambda loop=loop: (
                    (
                        callgrind_instructions(out, loop, CALLGRIND_CYCLES)
                        - callgrind_instructions(out, loop, 0)
                    )
                    / CALLGRIND_CYCLES
                ),
            )
            if cost is not None:
                per_cycle[loop] = cost
                say(f"  {loop}: {cost:.0f} instructions per cycle")
        result["callgrind"] = {"cycles": CALLGRIND_CYCLES, "instructions_per_cycle": per_cycle}
        say(f"the Rig's own lockstep cycle, natively (tools/rig_probe.py, {RIG_PROBE_CYCLES} cycles)")
        result["rig_probe"] = rig_probe_costs(not_measured)
        result["baseline"] = measure_baseline(out, args.baseline, not_measured, rig_probe_per_cycle)
    result["not_measured"] = not_measured
    write_json_atomically(out / "native.json", result)
    return 0
