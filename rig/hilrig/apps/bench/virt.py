"""`make bench`'s bare-metal image (`make baremetal`, build/qemu-virt/bin/joint-firmware-virt.elf):
its flash and RAM from its linker symbols (`size.image_size`, as the Cortex-M image's), and
the emulated cost of one control cycle: the image runs free under `qemu-system-arm -icount
shift=0` (virtual time: one nanosecond an instruction) on a qemu CAN bus of its own, measures
CYCLES of its cycles with the generic timer and prints them (boot parameter count-cycles;
hilrig.session.baremetal.parse_cycle_cost reads the line). The report sets the instructions per
cycle beside the Linux firmware's demo loop under callgrind (fw_cycle_count demo): the same
components and scheduler, x86-64 against Thumb-2, its inputs fed by the loop there and idle here.
"""

from __future__ import annotations

import subprocess
from collections.abc import Callable
from typing import Any

from hilrig import resources
from hilrig.apps.bench.common import ProbeError, bench_period_us, ratio_of
from hilrig.apps.bench.size import image_size, size_rows
from hilrig.errors import FirmwareError
from hilrig.session import baremetal

CYCLES = 2000
TIMEOUT_S = 300.0


def virt_size() -> dict[str, Any]:
    return image_size(resources.VIRT_IMAGE)


def virt_cycle_cost() -> dict[str, Any]:
    """Instructions per control cycle of the image under -icount (mean and worst of CYCLES)."""
    image = resources.VIRT_IMAGE
    if not image.exists():
        raise ProbeError(f"no {image}: make baremetal builds it")
    argv = baremetal.qemu_argv(
        image,
        None,
        node_id=1,
        period_us=bench_period_us(),
        mode="free",
        boot_extra=[f"count-cycles={CYCLES}"],
        icount=True,
    )
    argv[0] = baremetal.require_qemu(argv[0])
    done = subprocess.run(argv, capture_output=True, text=True, timeout=TIMEOUT_S, check=False)
    if done.returncode != 0:
        raise ProbeError(
            f"{' '.join(argv[:3])}... exited with {done.returncode}: {done.stdout[-300:]}{done.stderr[-300:]}"
        )
    try:
        cost = baremetal.parse_cycle_cost(done.stdout)
    except FirmwareError as error:
        raise ProbeError(str(error)) from error
    return {
        "cycles": cost.cycles,
        "instructions_per_cycle": cost.instructions_per_cycle,
        "worst": cost.worst_instructions,
    }


def virt_rows(row: Callable[..., None], native: dict[str, Any]) -> None:
    """The image's flash and RAM, and its instructions per cycle beside the Linux firmware's."""
    size_rows(row, native["virt_size"], image="bare-metal image (qemu-virt)")
    cost = native["virt_cycle"]
    linux = (native.get("callgrind") or {}).get("instructions_per_cycle", {}).get("demo")
    row(
        "instructions/cycle: bare-metal image under qemu -icount vs the Linux firmware under callgrind",
        f"{cost['instructions_per_cycle']:.0f} (worst {cost['worst']})",
        f"{linux:.0f}" if linux else "not measured",
        ratio_of(cost["instructions_per_cycle"], linux) if linux else None,
        cycles=cost["cycles"],
    )
