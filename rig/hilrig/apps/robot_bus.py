"""Which bit rate a robot needs: its modules' lockstep frames, cycle by cycle, on the timed bus
(`hilrig.wire.bustime`) at each standard bit rate, computed from the table's mapping rather than
run (a robot's run costs seconds per module; its schedule does not depend on the firmware).

Each cycle carries the master's SYNC, every module's enabled RPDOs (the rig sends each every
cycle, as `hilrig bus-load` counts a master), each module's TPDOs due at that SYNC (type n every
n-th, from its SYNC start value if it has one), each module's heartbeat when its producer time
comes round, and the master's heartbeat. The answer is the lowest bit rate at which no frame
waits for a later cycle (`needed_bitrate`), with each lower one's count of frames that did.

    robot_bitrate(BOARD_TABLE, range(1, 17), 1000, profile="lean").line()
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from boardproto.cia301 import (
    LAST_SYNCHRONOUS_TYPE,
    MASTER_HEARTBEAT_MS,
    MASTER_NODE_ID,
    SYNC_COB_ID,
    SYNC_COUNTER_MAX,
    heartbeat_cob_id,
    sync_counter,
)
from boardproto.table import BoardTable
from hilrig.wire.bustime import STANDARD_BITRATES, needed_bitrate

_ONE_BYTE = 1  # SYNC counter, heartbeat state
BEYOND_CLASSIC: tuple[int, ...] = (*STANDARD_BITRATES, 2_000_000, 4_000_000, 8_000_000)
"""The bit rates a robot's answer chooses from: the classic ones, then what a bus of classic
frames would need beyond them (how far a mapping is from fitting)."""


@dataclass(frozen=True)
class RobotBitrate:
    """The answer for one robot: the lowest standard bit rate that carries every frame in its
    cycle (None: none does) and, per bit rate, the frames that were not."""

    modules: int
    period_us: int
    profile: str
    cycles: int
    needed: int | None
    late: dict[int, int]

    def line(self) -> str:
        needs = f"needs {self.needed / 1e6:g} Mbit/s" if self.needed else "fits none of them"
        if self.needed and self.needed > max(STANDARD_BITRATES):
            needs += f" (beyond classic CAN's {max(STANDARD_BITRATES) / 1e6:g} Mbit/s)"
        late = ", ".join(f"{b / 1e3:g}k: {n}" for b, n in sorted(self.late.items()))
        return (
            f"{self.modules} modules, profile {self.profile}, {1e6 / self.period_us:g} Hz: {needs} "
            f"(frames not in their cycle over {self.cycles} cycles: {late})"
        )


def robot_cycles(
    table: BoardTable, node_ids: Iterable[int], period_us: int, cycles: int, master_heartbeat_ms: int
) -> list[list[tuple[int, int]]]:
    """(COB-ID, data length) of each cycle's frames, cycles 0 .. `cycles` - 1 (the modules enter
    operational before cycle 0: its SYNC is their first)."""
    ids = list(node_ids)
    rpdos = [p for p in table.rpdos if p.enabled and p.entries]
    tpdos = [p for p in table.tpdos if p.enabled and p.entries]
    heartbeat_every = _every(table.node.heartbeat_ms, period_us)
    master_every = _every(master_heartbeat_ms, period_us)
    out = []
    for n in range(cycles):
        frames = [(SYNC_COB_ID, _ONE_BYTE)]
        counter = sync_counter(n)
        for node in ids:
            frames += [(p.cob_id(node), p.length_bytes) for p in rpdos]
            frames += [
                (p.cob_id(node), p.length_bytes)
                for p in tpdos
                if _due(p.transmission_type, p.sync_start, n + 1, counter)
            ]
            if heartbeat_every and (n + node) % heartbeat_every == 0:  # the modules' own phases
                frames.append((heartbeat_cob_id(node), _ONE_BYTE))
        if master_every and n % master_every == 0:
            frames.append((heartbeat_cob_id(MASTER_NODE_ID), _ONE_BYTE))
        out.append(frames)
    return out


def robot_bitrate(
    table: BoardTable,
    node_ids: Iterable[int],
    period_us: int,
    *,
    profile: str,
    master_heartbeat_ms: int = MASTER_HEARTBEAT_MS,
    bitrates: Sequence[int] = BEYOND_CLASSIC,
) -> RobotBitrate:
    """The lowest of `bitrates` a robot of `node_ids` at `period_us` needs under the table's PDO
    `profile`, over the cycles in which every periodic frame has come round once."""
    mapped = table.with_pdo_profile(profile)
    ids = list(node_ids)
    periods = [
        p.transmission_type
        for p in mapped.tpdos
        if p.enabled and 1 <= p.transmission_type <= LAST_SYNCHRONOUS_TYPE
    ]
    periods += [_every(table.node.heartbeat_ms, period_us), _every(master_heartbeat_ms, period_us)]
    cycles = max([1, *periods]) + 1
    needed, late = needed_bitrate(
        robot_cycles(mapped, ids, period_us, cycles, master_heartbeat_ms), period_us, bitrates
    )
    return RobotBitrate(len(ids), period_us, profile, cycles, needed, late)


def _every(period_ms: int, period_us: int) -> int:
    return 0 if period_ms <= 0 else max(1, math.ceil(period_ms * 1000 / period_us))


def _due(transmission_type: int, sync_start: int, sync_number: int, counter: int) -> bool:
    """A synchronous TPDO of `transmission_type` at the `sync_number`-th SYNC since operational
    (with a SYNC start value: at the counters `sync_start` + k * type)."""
    if not 1 <= transmission_type <= LAST_SYNCHRONOUS_TYPE:
        return False  # event-driven or acyclic: not part of the cyclic schedule
    if sync_start:
        return (counter - sync_start) % transmission_type == 0 and counter <= SYNC_COUNTER_MAX
    return sync_number % transmission_type == 0


__all__ = ["BEYOND_CLASSIC", "RobotBitrate", "robot_bitrate", "robot_cycles"]
