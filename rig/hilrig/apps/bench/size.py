"""`make bench`'s size of the microcontroller build: the flash and RAM the Cortex-M4F firmware image
(`make cortex-m`, build/cortex-m/bin/joint-firmware.elf) takes, next to its budget.

Both figures and both budgets are symbols of the image, set by its linker scripts
(firmware/platform/cortex-m: sections.ld computes `__flash_used` and `__ram_used`, firmware.ld
states `__flash_budget` and `__ram_budget`), read here with `arm-none-eabi-nm`: the budget has one
home, the script the image is linked with. Flash: code, constants and the initial values of
.data; RAM: .data, .bss (the start-up arena and the recorder's samples included) and the stack.
An image over the chip's memory does not link at all; one over the budget is a row whose goal
is MISSED.
"""

from __future__ import annotations

import subprocess
from collections.abc import Callable
from pathlib import Path
from typing import Any

from hilrig.apps.bench.common import ROOT, ProbeError, ratio_of

FIRMWARE_IMAGE = ROOT / "build" / "cortex-m" / "bin" / "joint-firmware.elf"
SYMBOLS = ("__flash_used", "__flash_budget", "__ram_used", "__ram_budget")
NM = "arm-none-eabi-nm"
LABELS = {"flash": "flash", "ram": "RAM"}


def image_size(image: Path = FIRMWARE_IMAGE) -> dict[str, Any]:
    """The image's flash and RAM use and budget, in bytes, from its linker symbols."""
    if not image.exists():
        raise ProbeError(f"no {image}: make cortex-m builds it")
    try:
        listing = subprocess.run([NM, str(image)], check=True, capture_output=True, text=True).stdout
    except (OSError, subprocess.CalledProcessError) as error:
        hint = "apt-get install gcc-arm-none-eabi, or make deps"
        raise ProbeError(f"{NM} {image}: {error} ({hint})") from error
    values: dict[str, int] = {}
    for line in listing.splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[2] in SYMBOLS:
            values[parts[2]] = int(parts[0], 16)
    missing = [name for name in SYMBOLS if name not in values]
    if missing:
        raise ProbeError(f"{image} has no {', '.join(missing)}: not linked with firmware.ld")
    return {
        "image": str(image),
        "flash_bytes": values["__flash_used"],
        "flash_budget": values["__flash_budget"],
        "ram_bytes": values["__ram_used"],
        "ram_budget": values["__ram_budget"],
    }


def size_rows(
    row: Callable[..., None], size: dict[str, Any], image: str = "Cortex-M4F firmware image"
) -> None:
    """Two rows, flash and RAM of `image`: used, the budget, their ratio; the goal: within the
    budget."""
    for memory in ("flash", "ram"):
        used, budget = size[f"{memory}_bytes"], size[f"{memory}_budget"]
        ratio = ratio_of(used, budget)
        row(
            f"{image} {LABELS[memory]} (ratio: of the budget)",
            f"{used / 1024:.1f} KiB",
            f"{budget / 1024:.0f} KiB budget",
            ratio,
            "<= 1 (within budget)",
            ratio <= 1.0,
            used_bytes=used,
            budget_bytes=budget,
        )
