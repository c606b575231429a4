"""The firmware process's memory, as the soak watches it: VmRSS (and the exact page-table Rss of
smaps_rollup), anonymous huge pages and the open fd count, sampled from /proc (`sample_process`);
the verdict that it stayed flat after warm-up (`memory_verdict`); and transparent huge pages
turned off for the firmware (`disable_transparent_huge_pages`), since khugepaged would otherwise
grow its RSS on its own timer.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

DEFAULT_SAMPLE_EVERY = 1000
"""Cycles between samples of the firmware's RSS and fd count."""
DEFAULT_RSS_BOUND_KIB = 64
"""Allowed RSS growth from the end of warm-up to the end of the run [KiB].

The firmware allocates nothing after start-up (DESIGN: fixed arrays, no heap), and warm-up ends
only after every fault kind ran once, so every code path and the deepest stack it needs have
been touched by then: a flat process grows by 0 pages. The bound leaves 16 pages (64 KiB) for
page-granular noise that is not a leak: a rarely taken branch faulting in one more page of the
executable or of ASan's shadow of the stack. Anything that allocates per cycle or per fault
blows through it: one 16-byte allocation per cycle is 15 MB over a million cycles (more under
ASan, whose redzones and quarantine make even malloc/free churn without a leak show up as
growth, which is a finding too: no heap after start-up), one 1 KiB allocation per fault episode
is ~95 KiB over the ~95 episodes after warm-up."""


@dataclass(frozen=True)
class ProcessSample:
    cycle: int
    elapsed_s: float
    vm_rss_kib: int
    rss_anon_kib: int
    rss_exact_kib: int | None
    """Rss of /proc/PID/smaps_rollup: a page-table walk, exact (VmRSS may lag a few pages)."""
    fds: int
    cpu_s: float
    anon_huge_kib: int | None = None
    """AnonHugePages of smaps_rollup: what khugepaged collapsed (0 with THP disabled)."""


def sample_process(pid: int, cycle: int, elapsed_s: float) -> ProcessSample:
    """VmRSS, RssAnon, the exact Rss, open fds and CPU time of process `pid`."""
    status: dict[str, int] = {}
    with open(f"/proc/{pid}/status") as lines:
        for line in lines:
            name, _, rest = line.partition(":")
            if name in ("VmRSS", "RssAnon"):
                status[name] = int(rest.split()[0])
    rollup: dict[str, int] = {}
    with contextlib.suppress(OSError), open(f"/proc/{pid}/smaps_rollup") as lines:
        for line in lines:
            name, _, rest = line.partition(":")
            if name in ("Rss", "AnonHugePages"):
                rollup[name] = int(rest.split()[0])
    with open(f"/proc/{pid}/stat") as stat:
        fields = stat.read().rsplit(")", 1)[1].split()
    cpu_s = (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    return ProcessSample(
        cycle=cycle,
        elapsed_s=round(elapsed_s, 3),
        vm_rss_kib=status["VmRSS"],
        rss_anon_kib=status["RssAnon"],
        rss_exact_kib=rollup.get("Rss"),
        fds=len(os.listdir(f"/proc/{pid}/fd")),
        cpu_s=cpu_s,
        anon_huge_kib=rollup.get("AnonHugePages"),
    )


@dataclass(frozen=True)
class MemoryVerdict:
    ok: bool | None
    """None: not enough samples after warm-up to judge (a short or interrupted run)."""
    reason: str
    bound_kib: int
    warmup_cycle: int
    baseline_cycle: int | None = None
    rss_start_kib: int | None = None
    rss_warmup_kib: int | None = None
    rss_end_kib: int | None = None
    rss_max_after_warmup_kib: int | None = None
    growth_kib: int | None = None
    exact_growth_kib: int | None = None
    fds_warmup: int | None = None
    fds_end: int | None = None
    fds_max: int | None = None


def memory_verdict(samples: Sequence[ProcessSample], warmup_cycle: int, bound_kib: int) -> MemoryVerdict:
    """Flat memory: from the first sample at or after `warmup_cycle` to the last one, VmRSS (and
    the exact Rss, when known) grows by at most `bound_kib` and the fd count never changes."""
    after = [s for s in samples if s.cycle >= warmup_cycle]
    if len(after) < 2 or after[-1].cycle == after[0].cycle:
        return MemoryVerdict(
            None,
            f"inconclusive: {len(after)} sample(s) after warm-up (cycle {warmup_cycle}), need 2",
            bound_kib,
            warmup_cycle,
            rss_start_kib=samples[0].vm_rss_kib if samples else None,
            rss_end_kib=samples[-1].vm_rss_kib if samples else None,
        )
    base, end = after[0], after[-1]
    growth = end.vm_rss_kib - base.vm_rss_kib
    exact = (
        end.rss_exact_kib - base.rss_exact_kib
        if end.rss_exact_kib is not None and base.rss_exact_kib is not None
        else None
    )
    fds_changed = [s for s in after if s.fds != base.fds]
    problems = []
    if growth > bound_kib:
        problems.append(f"VmRSS grew {growth} KiB after warm-up, bound {bound_kib} KiB")
    if exact is not None and exact > bound_kib:
        problems.append(f"exact Rss grew {exact} KiB after warm-up, bound {bound_kib} KiB")
    if fds_changed:
        first = fds_changed[0]
        problems.append(f"open fds went from {base.fds} to {first.fds} at cycle {first.cycle}")
    reason = "; ".join(problems) or (
        f"flat: VmRSS {base.vm_rss_kib} -> {end.vm_rss_kib} KiB ({growth:+d}) from cycle {base.cycle} "
        f"to {end.cycle}, bound {bound_kib} KiB; fds {base.fds} throughout"
    )
    return MemoryVerdict(
        not problems,
        reason,
        bound_kib,
        warmup_cycle,
        baseline_cycle=base.cycle,
        rss_start_kib=samples[0].vm_rss_kib,
        rss_warmup_kib=base.vm_rss_kib,
        rss_end_kib=end.vm_rss_kib,
        rss_max_after_warmup_kib=max(s.vm_rss_kib for s in after),
        growth_kib=growth,
        exact_growth_kib=exact,
        fds_warmup=base.fds,
        fds_end=end.fds,
        fds_max=max(s.fds for s in samples),
    )



_PR_SET_THP_DISABLE = 41


def disable_transparent_huge_pages() -> str:
    """PR_SET_THP_DISABLE for this process and (inherited across fork and exec) the firmware it
    starts; returns what the report says about THP.

    With THP "always" (Debian's kernels, the micro-VM's), khugepaged collapses the firmware's
    sparse anonymous mappings (ASan's shadow and heap) into 2 MiB pages on its own timer: VmRSS
    jumps by megabytes a few seconds into the run, then stays flat, although the firmware
    touched no new page. That is the kernel's memory
    policy, not the firmware's use (a real board has no THP), and it would make a flat process
    look like it grew whenever a collapse lands after warm-up."""
    system = "unknown"
    with contextlib.suppress(OSError):
        system = Path("/sys/kernel/mm/transparent_hugepage/enabled").read_text().strip()
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.prctl(_PR_SET_THP_DISABLE, 1, 0, 0, 0) != 0:
        return f"system setting {system}; PR_SET_THP_DISABLE failed ({os.strerror(ctypes.get_errno())})"
    return f"disabled for the firmware (PR_SET_THP_DISABLE); system setting {system}"
