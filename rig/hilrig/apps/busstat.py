"""What a CAN bus really carries, measured from its frames (a live bus or a log file): the share
of the bit rate they take, frames per second of each COB-ID, error frames, and how late each
TPDO comes after its SYNC. `hilrig bus-load` computes the same load from the table; this
measures it, so the two can be held side by side::

    hilrig busstat bus.log -b 1M --rate-hz 1000     # a lockstep log, per SYNC at 1 kHz
    hilrig busstat -c can0 -b 1M --duration 10      # a live bus, for 10 s

Each frame counts with the bits of its data length, nominal and with worst-case stuffing, by
`hilrig.wire.framebits` (the formulas of `hilrig.apps.busload`; classic CAN 2.0A; an extended
id or FD frame counts as a classic one of its length, the safe side is not claimed for it).

Time base: without a rate, the frames' own timestamps (first to last frame): a real bus. With
`rate_hz`, the SYNCs: the frames from the first SYNC to the last one are `SYNCs - 1` cycles of
1 / rate_hz each. That is how a lockstep log is read (its wall time is the rig's pace, not the
bus's), and it is what `bus-load --rate-hz` assumes, frame for frame. Heartbeats are the one
traffic paced by wall time there (a node's timer): they count in the totals, but not in the
busiest cycle, which would otherwise be the cycle the host was slowest in (several heartbeats
in one cycle the rig was slow in, in a VM beside other load).

The delay of a TPDO after its SYNC is its timestamp minus the latest SYNC's, from the frames'
timestamps (a log from the receiving side holds the receive times).
"""

from __future__ import annotations

import statistics
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, TextIO

from boardproto.cia301 import SYNC_COB_ID, FunctionCode, function_of
from hilrig.wire.framebits import frame_bits

if TYPE_CHECKING:
    import can


@dataclass
class CobIdCount:
    """Frames of one COB-ID in the measured window."""

    frames: int = 0
    bits_worst_case: int = 0


@dataclass
class BusStats:
    """What the measured window held; `load` and `per_second` turn it into shares and rates."""

    frames: int = 0
    error_frames: int = 0
    remote_frames: int = 0
    bits_nominal: int = 0
    bits_worst_case: int = 0
    seconds: float = 0.0  # the window: by the timestamps, or SYNCs - 1 cycles of 1 / rate_hz
    cycles: int = 0  # complete SYNC cycles in the window (with rate_hz)
    busiest_cycle_bits: int = 0  # worst case (with rate_hz)
    by_cob_id: dict[int, CobIdCount] = field(default_factory=dict)
    delays_s: dict[int, list[float]] = field(default_factory=dict)  # TPDO COB-ID -> after its SYNC

    def load(self, bitrate: int, *, worst_case: bool = True) -> float:
        """Share of the bit rate (1.0 = 100 %) the window's frames took; 0 for an empty window."""
        if self.seconds <= 0:
            return 0.0
        bits = self.bits_worst_case if worst_case else self.bits_nominal
        return bits / self.seconds / bitrate

    def busiest_cycle_load(self, bitrate: int) -> float | None:
        """The busiest SYNC cycle's share of its period (worst case); None without rate_hz."""
        if not self.cycles:
            return None
        return self.busiest_cycle_bits / (self.seconds / self.cycles) / bitrate

    def per_second(self, cob_id: int) -> float:
        return self.by_cob_id[cob_id].frames / self.seconds if self.seconds > 0 else 0.0


def measure(
    frames: Iterable[can.Message], tpdo_cob_ids: Iterable[int], rate_hz: float | None = None
) -> BusStats:
    """Count `frames` (in time order). `tpdo_cob_ids`: the TPDOs whose delay after SYNC is
    measured. With `rate_hz` only the frames from the first SYNC up to the last one count (see
    the module's docstring); without it every frame does."""
    tpdos = frozenset(tpdo_cob_ids)
    stats = BusStats()
    first_t: float | None = None
    last_t = 0.0
    sync_t: float | None = None
    syncs = 0
    cycle_bits = 0
    pending: list[tuple[int, int, int, bool]] = []  # with rate_hz: the frames since the last SYNC
    for message in frames:
        if message.is_error_frame:
            stats.error_frames += 1
            continue
        cob_id = message.arbitration_id
        nominal = frame_bits(message.dlc, worst_case=False)
        worst = frame_bits(message.dlc, worst_case=True)
        is_sync = cob_id == SYNC_COB_ID and not message.is_extended_id
        if rate_hz is None:
            first_t = message.timestamp if first_t is None else first_t
            last_t = message.timestamp
            _count(stats, cob_id, nominal, worst, message.is_remote_frame)
        elif is_sync:
            if syncs:  # the cycle that this SYNC ends is complete: it counts
                for counted in pending:
                    _count(stats, *counted)
                stats.busiest_cycle_bits = max(stats.busiest_cycle_bits, cycle_bits)
            pending, cycle_bits = [], 0
            syncs += 1
        if rate_hz is not None and syncs:
            pending.append((cob_id, nominal, worst, message.is_remote_frame))
            if function_of(cob_id)[0] != FunctionCode.HEARTBEAT or message.is_extended_id:
                cycle_bits += worst
        if is_sync:
            sync_t = message.timestamp
        elif cob_id in tpdos and sync_t is not None:
            stats.delays_s.setdefault(cob_id, []).append(message.timestamp - sync_t)
    if rate_hz is None:
        stats.seconds = last_t - first_t if first_t is not None else 0.0
    else:
        stats.cycles = max(syncs - 1, 0)
        stats.seconds = stats.cycles / rate_hz
    return stats


def _count(stats: BusStats, cob_id: int, nominal: int, worst: int, remote: bool) -> None:
    stats.frames += 1
    stats.remote_frames += remote
    stats.bits_nominal += nominal
    stats.bits_worst_case += worst
    count = stats.by_cob_id.setdefault(cob_id, CobIdCount())
    count.frames += 1
    count.bits_worst_case += worst


def service_name(cob_id: int, names: Mapping[int, str]) -> str:
    """`names`' name for the COB-ID (the table's PDOs of the node), else its CiA 301 service
    and node ('HEARTBEAT node 0x7F')."""
    if cob_id in names:
        return names[cob_id]
    if cob_id == SYNC_COB_ID:
        return "SYNC"
    function, node = function_of(cob_id)
    try:
        service = FunctionCode(function).name
    except ValueError:
        return "-"
    service = "EMCY" if function == FunctionCode.SYNC_EMCY else service
    return f"{service} node 0x{node:02X}" if node else service


def _percent(share: float) -> str:
    return f"{100 * share:.1f} %"


def _microseconds(seconds: float) -> str:
    return f"{seconds * 1e6:.0f}"


def report(stats: BusStats, bitrate: int, names: Mapping[int, str], out: TextIO, *, per_cycle: bool) -> None:
    """The load, the frames of each COB-ID and the TPDO delays as text tables."""
    window = f"{stats.cycles} SYNC cycles ({stats.seconds:.6g} s)" if per_cycle else f"{stats.seconds:.6g} s"
    out.write(
        f"{stats.frames} frames in {window}, {stats.error_frames} error frames, "
        f"{stats.remote_frames} remote frames\n"
    )
    label = f"{bitrate / 1e6:g} Mbit/s" if bitrate >= 1_000_000 else f"{bitrate / 1e3:g} kbit/s"
    busiest = stats.busiest_cycle_load(bitrate)
    out.write(
        f"load of {label}: {_percent(stats.load(bitrate, worst_case=False))} nominal, "
        f"{_percent(stats.load(bitrate))} worst case"
        + (f", busiest cycle {_percent(busiest)}" if busiest is not None else "")
        + "\n\n"
    )
    rows = [["COB-ID", "frame", "frames", "per s"] + (["per cycle"] if per_cycle else [])]
    for cob_id in sorted(stats.by_cob_id):
        count = stats.by_cob_id[cob_id]
        row = [
            f"0x{cob_id:03X}",
            service_name(cob_id, names),
            str(count.frames),
            f"{stats.per_second(cob_id):.1f}",
        ]
        if per_cycle:
            row.append(f"{count.frames / stats.cycles:.3g}" if stats.cycles else "-")
        rows.append(row)
    _table(rows, out)
    if stats.delays_s:
        out.write("\nTPDO delay after its SYNC [us]\n")
        delay_rows = [["COB-ID", "frame", "count", "min", "median", "max"]]
        for cob_id in sorted(stats.delays_s):
            delays = stats.delays_s[cob_id]
            delay_rows.append(
                [
                    f"0x{cob_id:03X}",
                    service_name(cob_id, names),
                    str(len(delays)),
                    _microseconds(min(delays)),
                    _microseconds(statistics.median(delays)),
                    _microseconds(max(delays)),
                ]
            )
        _table(delay_rows, out)


def _table(rows: list[list[str]], out: TextIO) -> None:
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    for row in rows:
        out.write(
            "  ".join(
                cell.rjust(w) if i >= 2 else cell.ljust(w)
                for i, (cell, w) in enumerate(zip(row, widths, strict=True))
            ).rstrip()
            + "\n"
        )


__all__ = ["BusStats", "CobIdCount", "frame_bits", "measure", "report", "service_name"]
