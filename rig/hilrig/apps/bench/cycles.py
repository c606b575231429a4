"""`make bench`'s cycle budget of the microcontroller build: the worst control cycle of the
Cortex-M4F firmware (`make cortex-m`, build/cortex-m/bin/cm_cycle_budget.elf) in instructions,
counted under `qemu -icount shift=0` on its most expensive path (every TPDO due, an SDO upload in
progress, a fault being latched: firmware/platform/cortex-m/CycleBudget.hpp), against the
budget the table gives ([node] mcu_clock_hz and cycle_budget_percent, compiled into the image).

The image prints one line and exits 1 when the worst cycle is over the budget (the ctest
cortex_m.cycle_budget); this probe reads the line. qemu counts instructions, not core cycles:
the budget's share of the period is what leaves room for the rest.
"""

from __future__ import annotations

import os
import subprocess
from collections.abc import Callable
from pathlib import Path
from typing import Any

from hilrig.apps.bench.common import ROOT, ProbeError, ratio_of

BUDGET_IMAGE = ROOT / "build" / "cortex-m" / "bin" / "cm_cycle_budget.elf"
RUNNER = ROOT / "firmware" / "platform" / "cortex-m" / "run-test-image"
LINE_PREFIX = "cycle_budget: "


def cycle_budget(image: Path = BUDGET_IMAGE) -> dict[str, Any]:
    """The image's line as numbers: worst_instructions, worst_cycle, cycles, budget_cycles,
    period_us, mcu_clock_hz, budget_percent, budget_scale_percent (100: the table's budget)."""
    if not image.exists():
        raise ProbeError(f"no {image}: make cortex-m builds it")
    env = {**os.environ, "HIL_CORTEX_M_ICOUNT": "0", "HIL_CORTEX_M_TIMEOUT": "120"}
    try:
        run = subprocess.run([str(RUNNER), str(image)], capture_output=True, text=True, env=env, timeout=180)
    except (OSError, subprocess.TimeoutExpired) as error:
        raise ProbeError(f"{RUNNER.name} {image.name}: {error} (qemu-system-arm: make deps)") from error
    output = run.stdout + run.stderr  # semihosting writes to qemu's stderr
    line = next((text for text in output.splitlines() if text.startswith(LINE_PREFIX)), None)
    if line is None:
        raise ProbeError(
            f"{image.name} printed no '{LINE_PREFIX}' line (exit {run.returncode}): {run.stderr.strip()}"
        )
    values = {
        name: int(value) for name, value in (part.split("=") for part in line[len(LINE_PREFIX) :].split())
    }
    return {"image": str(image), "within_budget": run.returncode == 0, **values}


def cycle_budget_rows(row: Callable[..., None], measured: dict[str, Any]) -> None:
    """One row: the worst cycle's instructions, the budget's cycles, their ratio; the goal:
    within the budget."""
    worst, budget = measured["worst_instructions"], measured["budget_cycles"]
    ratio = ratio_of(worst, budget)
    clock = measured["mcu_clock_hz"] / 1e6
    row(
        f"Cortex-M4F worst control cycle under qemu -icount (ratio: of {measured['budget_percent']} % "
        f"of {measured['period_us']} us at {clock:g} MHz)",
        f"{worst} instructions",
        f"{budget} cycles budget",
        ratio,
        "<= 1 (within budget)",
        ratio <= 1.0,
        **measured,
    )
