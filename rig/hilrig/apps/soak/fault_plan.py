"""The soak's seeded fault schedule: about one fault per `interval` cycles, every kind once
during warm-up, the same plan for the same arguments (`plan_faults`). The kinds are spelled as
`hilrig.session.faults` spells them, one vocabulary for `hilrig sim --fault` and the soak, each
with the outcome the soak checks.
"""

from __future__ import annotations

import enum
import itertools
import random
from collections import Counter
from dataclasses import dataclass

from hilrig.apps.soak.layout import MAX_EXTRA_STALE_CYCLES, SoakLayout
from hilrig.session.faults import FaultKind

DEFAULT_FAULT_INTERVAL = 10_000
"""About one fault per this many cycles (seeded jitter of +-1/4 interval)."""
MAX_STOPPED_SYNCS = 5


class SoakFault(enum.StrEnum):
    """The faults the soak injects, spelled as `hilrig.session.faults` spells them (one vocabulary for
    `hilrig sim --fault` and the soak), each with the outcome the soak checks."""

    MALFORMED_RPDO = f"{FaultKind.MALFORMED}:length"
    """The sensor RPDO a few bytes short: EMCY 0x8210, then the error reset."""
    UNKNOWN_COB_ID = f"{FaultKind.MALFORMED}:cob-id"
    """A frame on a COB-ID the node does not use: its acceptance filter drops it (never received)."""
    SDO_UPLOAD = f"{FaultKind.SDO_READ}"
    """An SDO upload between two cycles, answered with the right value."""
    STALE_SENSOR = f"{FaultKind.DROP}:sensors"
    """The sensor RPDO withheld: the encoder-stale faults latch at exactly the limit."""
    NMT_STOP_START = f"{FaultKind.NMT_STOP}"
    """NMT stop, SYNCs that must go unanswered, NMT start."""



@dataclass(frozen=True)
class PlannedFault:
    cycle: int
    """Firmware cycle (SYNCs while operational, 1 = first) whose SYNC the fault comes before."""
    kind: SoakFault
    arg: int
    """Kind-specific, drawn from the seed: the malformed frame's length, the unknown COB-ID, the
    SDO object (modulo the list), cycles withheld beyond the stale limit, SYNCs while stopped."""


@dataclass(frozen=True)
class FaultPlan:
    faults: tuple[PlannedFault, ...]
    warmup_cycle: int
    """Memory is judged from the first sample at or after this cycle: half an interval after the
    first round of faults (every kind once), or half the run when the round does not fit."""
    seed: int
    interval: int

    def counts(self) -> dict[str, int]:
        return dict(Counter(f.kind.value for f in self.faults))


def min_fault_interval(layout: SoakLayout) -> int:
    """Episodes must not overlap: the longest (stale sensor) takes about encoder_stale_cycles
    + MAX_EXTRA_STALE_CYCLES + 3 cycles; keep four times that between faults."""
    return 4 * (layout.encoder_stale_cycles + MAX_EXTRA_STALE_CYCLES + 3)


def plan_faults(cycles: int, interval: int, seed: int, layout: SoakLayout) -> FaultPlan:
    """One fault about every `interval` cycles (+-interval/4, seeded), none in the last half
    interval; the first len(FaultKind) are every kind once in a seeded order. Same arguments,
    same plan."""
    if interval < min_fault_interval(layout):
        raise ValueError(f"fault interval: expected >= {min_fault_interval(layout)} cycles, got {interval}")
    rng = random.Random(seed)
    kinds = list(SoakFault)
    first_round = rng.sample(kinds, len(kinds))
    unknown_ids = layout.unknown_cob_ids()
    faults: list[PlannedFault] = []
    for i in itertools.count():
        nominal = (i + 1) * interval
        if nominal + interval // 2 > cycles:
            break
        at = nominal + (rng.randint(-(interval // 4), interval // 4) if i else 0)
        kind = first_round[i] if i < len(first_round) else rng.choice(kinds)
        arg = {
            SoakFault.MALFORMED_RPDO: lambda: rng.randrange(layout.sensor.length),
            SoakFault.UNKNOWN_COB_ID: lambda: rng.choice(unknown_ids),
            SoakFault.SDO_UPLOAD: lambda: rng.randrange(1 << 16),
            SoakFault.STALE_SENSOR: lambda: rng.randint(1, MAX_EXTRA_STALE_CYCLES),
            SoakFault.NMT_STOP_START: lambda: rng.randint(1, MAX_STOPPED_SYNCS),
        }[kind]()
        faults.append(PlannedFault(at, kind, arg))
    round_done = len(faults) >= len(kinds)
    warmup = faults[len(kinds) - 1].cycle + interval // 2 if round_done else cycles // 2
    return FaultPlan(tuple(faults), warmup, seed, interval)

