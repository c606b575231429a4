"""Bus load of the lockstep exchange on a real CAN bus ("will my trace mapping fit?").

The virtual bus has no bit rate; a real one does. For a PDO layout (`boardproto.load_table`)
and a control-cycle rate this module counts the frames of each cycle and the share of a
125 k / 250 k / 500 k / 1 Mbit/s bus they take, nominal and with worst-case bit stuffing, as
classic CAN frames or as CAN FD frames (with a faster data phase or without)::

    hilrig bus-load --rate-hz 1000 --bitrate 500k --table protocol/board.toml
    hilrig bus-load --bitrate 500k --data-bitrate 2M      # the same PDOs as CAN FD frames

Frame length, classic CAN 2.0A data frame (11-bit identifier) with n data bytes:

    nominal bits   = 47 + 8n
        SOF 1 + identifier 11 + RTR 1 + IDE 1 + r0 1 + DLC 4 + data 8n + CRC 15
        + CRC delimiter 1 + ACK slot 1 + ACK delimiter 1 + end of frame 7 + intermission 3
    stuff bits     = floor((34 + 8n - 1) / 4)   (worst case)
        only SOF .. CRC (34 + 8n bits) is stuffed; after the first stuff bit every further one
        can come after 4 more bits, because a stuff bit itself starts the next run of 5.
    worst-case     = 47 + 8n + floor((34 + 8n - 1) / 4)

So an 8-byte frame is 111 bits nominal and 135 worst case; a 1-byte SYNC 55 and 65. The
worst-case formula is the one of R. I. Davis, A. Burns, R. J. Bril, J. J. Lukkien, "Controller
Area Network (CAN) schedulability analysis: Refuted, revisited and revised", Real-Time Systems
35(3), 2007 (section 3). The older Tindell/Burns bound floor((34 + 8n) / 5) gives 130 bits for
8 bytes and undercounts; tables that say 132 use yet other conventions (e.g. no intermission
and a different stuff bound). We use the 135 convention: it is the safe one for a budget.

CAN FD base-format data frame (ISO 11898-1:2015) with n data bytes (n padded up to a length a
DLC can say: 0..8, 12, 16, 20, 24, 32, 48, 64). With a bit rate switch the bits from ESI to the
CRC are sent at the data bit rate, the rest at the nominal (arbitration) bit rate:

    at the nominal rate  A = 30
        SOF 1 + identifier 11 + RRS 1 + IDE 1 + FDF 1 + res 1 + BRS 1               (17, before
        the switch) + CRC delimiter 1 + ACK slot 1 + ACK delimiter 1 + end of frame 7
        + intermission 3                                                              (13, after)
    at the data rate     D = 5 + 8n + 4 + c + ceil((4 + c) / 4)
        ESI 1 + DLC 4 + data 8n + stuff count 4 (3 bits + parity) + CRC c (17 for n <= 16,
        21 above) + the fixed stuff bits of stuff count and CRC: one before them and one after
        every 4 bits (6 with CRC-17, 7 with CRC-21)
    dynamic stuff bits   S = floor((22 + 8n - 1) / 4)   (worst case, as for classic CAN)
        SOF .. end of data (22 + 8n bits) is stuffed dynamically; at most 3 of them fall
        before the switch (after bits 5, 9, 13), counted at the nominal rate, the rest at
        the data rate
    frame time           A / nominal + D / data   (nominal: no dynamic stuff bits)
                         (A + 3) / nominal + (D + S - 3) / data   (worst case)

The CRC delimiter, during which the rate switches back, is counted whole at the nominal rate
(the safe side). Without a switch (--fd without --data-bitrate) both rates are the nominal one.
So an 8-byte FD frame at 500 kbit/s with a 2 Mbit/s data phase takes 30/500k + 96/2M =
108 us, worst case 33/500k + 114/2M = 123 us (a classic one: 222 us, worst case 270 us).

What one lockstep cycle puts on the bus (`lockstep_traffic`):
  * every enabled RPDO that maps something: the rig sends each of them every cycle;
  * SYNC with its 1-byte counter, every cycle;
  * each enabled TPDO by transmission type: n in 1..240 every n-th SYNC; 0 (acyclic
    synchronous) counted as every SYNC (the worst case: values change every cycle); 254/255
    (event driven) at most once per cycle (the board changes once per cycle), limited by the
    inhibit time, and at least at the event-timer rate;
  * the node's heartbeat (1 byte) every heartbeat_ms, independent of the cycle.

A robot (`lockstep_traffic(..., node_ids=[1, .., N], master_heartbeat_ms=20)`, `hilrig
bus-load --modules N`): N identical modules on one bus, each with the frames above under its
own COB-IDs (base + node id), but ONE SYNC per cycle for all, plus the master's heartbeat
(1 byte on `heartbeat_cob_id(MASTER_NODE_ID)`) every master_heartbeat_ms. The report shows one
row per kind with its count and COB-ID range (`RPDO1 x8  0x201..0x208`); the sums count every
frame.

Bus load = busy time per second, averaged over time. The peak cycle (every synchronous TPDO
due at once) must also fit in one cycle period: that share is reported beside it. Above 70 %
(worst case, or the busiest cycle) a WARNING line; above 100 % the exchange does not fit.

`highest_rate_hz` turns that around: the highest cycle rate (0.1 Hz steps) at which both
stay within 70 % (worst case), by bisection on the rate (both loads grow with it; see there).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import TextIO

from boardproto import BoardTable, Pdo
from boardproto.cia301 import (
    EVENT_DRIVEN_TYPES,
    LAST_SYNCHRONOUS_TYPE,
    MASTER_HEARTBEAT_MS,
    MASTER_NODE_ID,
    SYNC_COB_ID,
    heartbeat_cob_id,
)
from hilrig.wire.bustime import STANDARD_BITRATES as STANDARD_BITRATES  # the bit rates reported
from hilrig.wire.framebits import MAX_DATA_BYTES as MAX_DATA_BYTES  # the frame arithmetic's home
from hilrig.wire.framebits import frame_bits_nominal as frame_bits_nominal
from hilrig.wire.framebits import frame_bits_worst_case as frame_bits_worst_case
from hilrig.wire.framebits import stuff_bits_worst_case as stuff_bits_worst_case

WARNING_LOAD = 0.70
"""Above this share of the bus (worst-case stuffing) the command prints a WARNING line."""
FULL_LOAD = 1.0
"""Above this share the exchange does not fit the bus (`hilrig bus-load` exits with 1)."""

DEFAULT_RATE_HZ = 1000.0
SYNC_DATA_BYTES = 1  # the SYNC counter
HEARTBEAT_DATA_BYTES = 1
DEFAULT_MASTER_NODE_ID = MASTER_NODE_ID
"""The rig as the master of a robot: its heartbeat goes on `heartbeat_cob_id` of this id."""
DEFAULT_MASTER_HEARTBEAT_MS = MASTER_HEARTBEAT_MS
RATE_STEPS_PER_HZ = 10
"""`highest_rate_hz` answers to 0.1 Hz."""

FD_DATA_LENGTHS = (0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64)
"""The data field lengths of a CAN FD frame (DLC 0..15); a payload is padded to the next one."""

_FD_ARBITRATION_BITS = 17  # SOF, identifier 11, RRS, IDE, FDF, res, BRS: before the switch
_FD_ARBITRATION_STUFF_BITS = 3  # the most dynamic stuff bits before the switch (after 5, 9, 13)
_FD_TAIL_BITS = 13  # CRC delimiter, ACK slot, ACK delimiter, end of frame 7, intermission 3
_FD_CONTROL_BITS = 5  # ESI, DLC 4
_FD_STUFF_COUNT_BITS = 4  # 3-bit stuff count + parity
_FD_CRC17_MAX_BYTES = 16  # CRC-17 up to 16 data bytes, CRC-21 above
_FD_CRC17_BITS = 17
_FD_CRC21_BITS = 21


def fd_data_length(data_bytes: int) -> int:
    """The data field a CAN FD frame needs for `data_bytes` bytes: 9 -> 12, 33 -> 48."""
    for length in FD_DATA_LENGTHS:
        if length >= data_bytes >= 0:
            return length
    raise ValueError(f"a CAN FD frame carries 0..64 data bytes, got {data_bytes}")


def fd_frame_bits(data_bytes: int, *, worst_case: bool) -> tuple[int, int]:
    """(bits at the nominal bit rate, bits at the data bit rate) of a CAN FD base-format data
    frame: (30, 5 + 8n + 4 + c + ceil((4 + c) / 4)), plus, in the worst case, 3 dynamic stuff
    bits at the nominal rate and floor((22 + 8n - 1) / 4) - 3 at the data rate (see the module)."""
    n = fd_data_length(data_bytes)
    crc_bits = _FD_CRC17_BITS if n <= _FD_CRC17_MAX_BYTES else _FD_CRC21_BITS
    fixed_stuff_bits = -(-(_FD_STUFF_COUNT_BITS + crc_bits) // 4)  # ceil: one per 4 bits, one first
    nominal = _FD_ARBITRATION_BITS + _FD_TAIL_BITS
    data = _FD_CONTROL_BITS + 8 * n + _FD_STUFF_COUNT_BITS + crc_bits + fixed_stuff_bits
    if worst_case:
        dynamic = (_FD_ARBITRATION_BITS + _FD_CONTROL_BITS + 8 * n - 1) // 4
        before_switch = min(dynamic, _FD_ARBITRATION_STUFF_BITS)
        nominal += before_switch
        data += dynamic - before_switch
    return nominal, data


@dataclass(frozen=True)
class BusRates:
    """The bit rates of a bus: classic CAN at `bitrate`, or CAN FD (`fd`, or implied by
    `data_bitrate`) with its data phase at `data_bitrate`, or at `bitrate` without a switch."""

    bitrate: int  # bit/s, nominal (arbitration)
    data_bitrate: int | None = None  # bit/s, CAN FD data phase (bit rate switch)
    fd: bool = False

    def __post_init__(self) -> None:
        if self.bitrate <= 0 or (self.data_bitrate is not None and self.data_bitrate <= 0):
            raise ValueError(f"bit rates must be positive, got {self.bitrate} and {self.data_bitrate}")

    @property
    def is_fd(self) -> bool:
        return self.fd or self.data_bitrate is not None

    def frame_seconds(self, data_bytes: int, *, worst_case: bool) -> float:
        """Time one data frame with `data_bytes` bytes takes on this bus."""
        if not self.is_fd:
            bits = frame_bits_worst_case(data_bytes) if worst_case else frame_bits_nominal(data_bytes)
            return bits / self.bitrate
        nominal, data = fd_frame_bits(data_bytes, worst_case=worst_case)
        return nominal / self.bitrate + data / (self.data_bitrate or self.bitrate)

    @property
    def label(self) -> str:
        """'500 kbit/s', '500 kbit/s FD', '500 kbit/s + 2 Mbit/s FD'."""
        if not self.is_fd:
            return _bitrate_label(self.bitrate)
        data = f" + {_bitrate_label(self.data_bitrate)}" if self.data_bitrate else ""
        return f"{_bitrate_label(self.bitrate)}{data} FD"


@dataclass(frozen=True)
class Traffic:
    """One periodic frame on the bus, or `count` frames of one kind from as many nodes (the
    same PDO of every module of a robot): each of them `per_second`, COB-IDs `can_id` ..
    `highest_can_id`."""

    name: str  # "RPDO1", "SYNC", "TPDO8", "heartbeat"
    can_id: int  # the lowest COB-ID of the kind
    data_bytes: int
    per_second: float  # average frames per second, of each of the `count` frames
    in_peak_cycle: bool  # sent in the cycle where every synchronous TPDO is due
    count: int = 1
    highest_can_id: int | None = None  # None: every frame of the kind has `can_id`
    sync_phase: tuple[int, int] | None = None
    """A TPDO with a SYNC start value: (type n, start value s), due at the SYNC counters c with
    (c - s) % n == 0 only, so it falls into the busiest cycle only where its turn is; None: any
    cycle may hold it (`in_peak_cycle` says)."""

    def __post_init__(self) -> None:
        if self.count < 1:
            raise ValueError(f"{self.name}: a frame kind counts 1 frame or more, got {self.count}")
        if self.highest_can_id is not None and self.highest_can_id < self.can_id:
            raise ValueError(f"{self.name}: highest COB-ID below the lowest")

    @property
    def bits_nominal(self) -> int:
        return frame_bits_nominal(self.data_bytes)

    @property
    def bits_worst_case(self) -> int:
        return frame_bits_worst_case(self.data_bytes)


@dataclass(frozen=True)
class BusLoad:
    """Share of one bus (1.0 = 100 %) the traffic takes at `rates`."""

    rates: BusRates
    nominal: float  # average, no stuff bits
    worst_case: float  # average, worst-case stuffing
    peak_cycle_worst_case: float  # the busiest cycle's time / the cycle period

    @property
    def bitrate(self) -> int:
        return self.rates.bitrate

    @property
    def warning(self) -> bool:
        return self.worst_case > WARNING_LOAD or self.peak_cycle_worst_case > WARNING_LOAD

    @property
    def overloaded(self) -> bool:
        """The exchange does not fit: on average, or in its busiest cycle (worst-case stuffing)."""
        return self.worst_case > FULL_LOAD or self.peak_cycle_worst_case > FULL_LOAD


def _check_rate(rate_hz: float) -> None:
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"the cycle rate must be a positive number of Hz, got {rate_hz}")


def bus_load(traffic: Iterable[Traffic], rate_hz: float, bitrate: int | BusRates) -> BusLoad:
    """Average and peak-cycle share of a bus taken by `traffic` at `rate_hz` cycles/s; `bitrate`
    is a classic CAN bit rate in bit/s, or the BusRates of a CAN FD bus."""
    _check_rate(rate_hz)
    rates = bitrate if isinstance(bitrate, BusRates) else BusRates(bitrate)
    items = list(traffic)
    nominal = sum(t.count * t.per_second * rates.frame_seconds(t.data_bytes, worst_case=False) for t in items)
    worst = sum(t.count * t.per_second * rates.frame_seconds(t.data_bytes, worst_case=True) for t in items)
    peak = _peak_cycle_seconds(items, rates)
    return BusLoad(rates=rates, nominal=nominal, worst_case=worst, peak_cycle_worst_case=peak * rate_hz)


def _peak_cycle_seconds(traffic: Iterable[Traffic], rates: BusRates) -> float:
    """Bus time of the busiest cycle (worst-case stuffing): every frame of `traffic` that can
    fall into it, once each; of the TPDOs that take turns by SYNC counter (`sync_phase`), those
    of the counter where most of them meet."""
    items = list(traffic)
    anywhere = sum(
        t.count * rates.frame_seconds(t.data_bytes, worst_case=True)
        for t in items
        if t.in_peak_cycle and t.sync_phase is None
    )
    turns = [t for t in items if t.sync_phase is not None]
    if not turns:
        return anywhere
    period = math.lcm(*(t.sync_phase[0] for t in turns if t.sync_phase is not None))
    busiest = max(
        sum(
            t.count * rates.frame_seconds(t.data_bytes, worst_case=True)
            for t in turns
            if t.sync_phase is not None and (counter - t.sync_phase[1]) % t.sync_phase[0] == 0
        )
        for counter in range(1, period + 1)
    )
    return anywhere + busiest


def _tpdo_per_second(pdo: Pdo, rate_hz: float) -> float:
    kind = pdo.transmission_type
    if kind == 0:
        return rate_hz  # acyclic synchronous: worst case, a change every cycle
    if kind <= LAST_SYNCHRONOUS_TYPE:
        return rate_hz / kind
    if kind in EVENT_DRIVEN_TYPES:
        per_second = rate_hz  # a change at most once per control cycle
        if pdo.inhibit_time_100us:
            per_second = min(per_second, 10_000 / pdo.inhibit_time_100us)
        if pdo.event_timer_ms:
            per_second = max(per_second, 1000 / pdo.event_timer_ms)
        return per_second
    raise ValueError(f"{pdo.name}: transmission type {kind} is not supported")


def _node_traffic(table: BoardTable, rate_hz: float, node: int) -> tuple[list[Traffic], list[Traffic]]:
    """The per-node rule, one node's frames: (what the master sends it: its RPDOs; what it
    sends: its TPDOs and heartbeat)."""
    received = [
        Traffic(pdo.name, pdo.cob_id(node), pdo.length_bytes, rate_hz, True)
        for pdo in table.rpdos
        if pdo.enabled and pdo.entries
    ]
    sent: list[Traffic] = []
    for pdo in table.tpdos:
        if pdo.enabled and pdo.entries:
            # In the busiest cycle every synchronous TPDO is due at once (and an event-driven
            # one may fire too).
            per_second = _tpdo_per_second(pdo, rate_hz)
            phase = (pdo.transmission_type, pdo.sync_start) if pdo.sync_start else None
            sent.append(
                Traffic(pdo.name, pdo.cob_id(node), pdo.length_bytes, per_second, True, sync_phase=phase)
            )
    if table.node.heartbeat_ms:
        sent.append(
            Traffic(
                "heartbeat",
                heartbeat_cob_id(node),
                HEARTBEAT_DATA_BYTES,
                1000 / table.node.heartbeat_ms,
                True,  # it can fall into the busiest cycle too
            )
        )
    return received, sent


def _grouped(per_node: Sequence[Sequence[Traffic]]) -> list[Traffic]:
    """One Traffic per frame kind out of the same kinds of several nodes (identical modules:
    the same rows in the same order), counting them all."""
    if len(per_node) == 1:
        return list(per_node[0])
    grouped = []
    for kinds in zip(*per_node, strict=True):
        first = kinds[0]
        can_ids = [t.can_id for t in kinds]
        grouped.append(
            Traffic(
                first.name,
                min(can_ids),
                first.data_bytes,
                first.per_second,
                first.in_peak_cycle,
                count=len(kinds),
                highest_can_id=max(can_ids),
                sync_phase=first.sync_phase,
            )
        )
    return grouped


def _check_distinct_cob_ids(per_node: dict[int, list[Traffic]], master_node_id: int | None) -> None:
    """Two frames on one identifier cannot share a bus: PDO 5..8 of node N use the COB-IDs of
    PDO 1..4 of node N + 64 in the default layout, and a table may set its own bases."""
    owner: dict[int, str] = {SYNC_COB_ID: "SYNC"}
    if master_node_id is not None:
        owner[heartbeat_cob_id(master_node_id)] = "the master's heartbeat"
    for node, frames in per_node.items():
        for frame in frames:
            name = f"{frame.name} of node {node}"
            if frame.can_id in owner:
                raise ValueError(
                    f"COB-ID 0x{frame.can_id:03X} of {name} is also that of {owner[frame.can_id]}"
                )
            owner[frame.can_id] = name


def lockstep_traffic(
    table: BoardTable,
    rate_hz: float,
    node_id: int | None = None,
    *,
    node_ids: Sequence[int] | None = None,
    master_heartbeat_ms: float | None = None,
    master_node_id: int = DEFAULT_MASTER_NODE_ID,
) -> list[Traffic]:
    """The frames of the lockstep exchange for the table's default PDO layout (see the module
    docstring for what counts and how often): of the node `node_id` (default: the table's), or
    of a robot, identical modules with `node_ids` on one bus, one row per frame kind with its
    count. `master_heartbeat_ms` adds the master's heartbeat (0 or None: it sends none)."""
    _check_rate(rate_hz)
    if node_ids is not None and node_id is not None:
        raise ValueError("give node_id (one node) or node_ids (a robot), not both")
    if node_ids is not None and (not node_ids or len(set(node_ids)) != len(node_ids)):
        raise ValueError(f"a robot needs distinct node ids, got {list(node_ids)}")
    if master_heartbeat_ms is not None and master_heartbeat_ms < 0:
        raise ValueError(
            f"the master's heartbeat period must be 0 (none) or positive, got {master_heartbeat_ms}"
        )
    nodes = (
        list(node_ids)
        if node_ids is not None
        else [table.node.default_node_id if node_id is None else node_id]
    )
    if master_heartbeat_ms and master_node_id in nodes:
        raise ValueError(f"node id 0x{master_node_id:02X} is the master's")
    per_node = {node: _node_traffic(table, rate_hz, node) for node in nodes}
    if len(nodes) > 1:
        _check_distinct_cob_ids(
            {node: [*received, *sent] for node, (received, sent) in per_node.items()},
            master_node_id if master_heartbeat_ms else None,
        )
    traffic = _grouped([received for received, _ in per_node.values()])
    traffic.append(Traffic("SYNC", SYNC_COB_ID, SYNC_DATA_BYTES, rate_hz, True))  # one for all nodes
    traffic.extend(_grouped([sent for _, sent in per_node.values()]))
    if master_heartbeat_ms:
        traffic.append(
            Traffic(
                "master heartbeat",
                heartbeat_cob_id(master_node_id),
                HEARTBEAT_DATA_BYTES,
                1000 / master_heartbeat_ms,
                True,  # as the nodes' heartbeats: it can fall into the busiest cycle
            )
        )
    return traffic


def _fits(load: BusLoad, max_load: float) -> bool:
    """The `BusLoad.warning` rule with `max_load` for 70 %: average and busiest cycle, worst case."""
    return load.worst_case <= max_load and load.peak_cycle_worst_case <= max_load


def highest_rate_hz(
    table: BoardTable,
    bitrate: int | BusRates,
    *,
    max_load: float = WARNING_LOAD,
    node_id: int | None = None,
    node_ids: Sequence[int] | None = None,
    master_heartbeat_ms: float | None = None,
    master_node_id: int = DEFAULT_MASTER_NODE_ID,
) -> float:
    """The highest SYNC (cycle) rate, a multiple of 0.1 Hz, at which the lockstep exchange of
    `lockstep_traffic(table, ..., node_id, node_ids=..., master_heartbeat_ms=...)` takes at most
    `max_load` of the bus on average and in its busiest cycle, both with worst-case stuffing
    (what `BusLoad.warning` judges); 0.0 when not even 0.1 Hz fits (heartbeats or event timers
    alone take more).

    Both loads are nondecreasing in the rate: the busiest cycle is rate x its (rate-independent)
    frames; the average sums per-frame rates that are each constant (heartbeats, event timers),
    proportional (RPDOs, SYNC, synchronous TPDOs) or min/max-clipped (inhibit time, event timer)
    in the rate. So whether it fits flips once, and a bisection on the 0.1 Hz grid finds the
    exact step, whichever of the two limits binds and wherever a clip sits.
    """
    rates = bitrate if isinstance(bitrate, BusRates) else BusRates(bitrate)

    def traffic_at(rate: float) -> list[Traffic]:
        return lockstep_traffic(
            table,
            rate,
            node_id,
            node_ids=node_ids,
            master_heartbeat_ms=master_heartbeat_ms,
            master_node_id=master_node_id,
        )

    def fits(tenths: int) -> bool:
        rate = tenths / RATE_STEPS_PER_HZ
        return _fits(bus_load(traffic_at(rate), rate, rates), max_load)

    if not fits(1):
        return 0.0
    # The busiest cycle alone bounds the rate: max_load / its bus time (at least one SYNC).
    peak_s = _peak_cycle_seconds(traffic_at(1.0), rates)
    fitting, too_fast = 1, math.floor(max_load / peak_s * RATE_STEPS_PER_HZ) + 1
    while fits(too_fast):  # only float rounding at the bound could get here
        fitting, too_fast = too_fast, 2 * too_fast
    while too_fast - fitting > 1:
        middle = (fitting + too_fast) // 2
        if fits(middle):
            fitting = middle
        else:
            too_fast = middle
    return fitting / RATE_STEPS_PER_HZ


def robot_load_line(
    table: BoardTable,
    node_ids: Sequence[int],
    rate_hz: float,
    *,
    profile: str,
    master_heartbeat_ms: float | None = None,
    bitrate: int = 1_000_000,
) -> str:
    """One line: what a real bus at `bitrate` would carry for a robot of `node_ids` at `rate_hz`
    under PDO profile `profile` of the table (as `lockstep_traffic(..., node_ids=...)` and
    `bus_load` count it, worst-case stuffing), and the highest rate that stays within 70 %;
    e.g. for the summary of a robot run on the virtual bus, which has no bit rate."""
    mapped = table.with_pdo_profile(profile)
    traffic = lockstep_traffic(mapped, rate_hz, node_ids=node_ids, master_heartbeat_ms=master_heartbeat_ms)
    load = bus_load(traffic, rate_hz, bitrate)
    highest = highest_rate_hz(mapped, bitrate, node_ids=node_ids, master_heartbeat_ms=master_heartbeat_ms)
    verdict = " OVERLOAD" if load.overloaded else " WARNING" if load.warning else ""
    return (
        f"profile {profile}, {len(node_ids)} module{'s' if len(node_ids) > 1 else ''} at {rate_hz:g} Hz "
        f"on {_bitrate_label(bitrate)}: "
        f"{_percent(load.worst_case)} worst case, busiest cycle {_percent(load.peak_cycle_worst_case)}"
        f"{verdict}; within {_percent(WARNING_LOAD)} up to {highest:g} Hz"
    )


# --- report -----------------------------------------------------------------------------


def _percent(share: float) -> str:
    return f"{100 * share:.1f} %"


def _format_rate(per_second: float, rate_hz: float) -> str:
    per_cycle = per_second / rate_hz
    return f"{per_cycle:g}" if per_cycle >= 0.01 else f"{per_second:g}/s"


def _bitrate_label(bitrate: int) -> str:
    if bitrate % 1_000_000 == 0:
        return f"{bitrate // 1_000_000} Mbit/s"
    if bitrate % 1000 == 0:
        return f"{bitrate // 1000} kbit/s"
    return f"{bitrate} bit/s"


def _table(rows: Sequence[Sequence[str]], out: TextIO) -> None:
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    for row in rows:
        cells = [
            cell.ljust(w) if i == 0 else cell.rjust(w)
            for i, (cell, w) in enumerate(zip(row, widths, strict=True))
        ]
        print("  ".join(cells).rstrip(), file=out)


def _cob_ids(traffic: Traffic) -> str:
    """'0x210', or for one kind of frame of several nodes '0x201..0x208'."""
    if traffic.highest_can_id is None or traffic.highest_can_id == traffic.can_id:
        return f"0x{traffic.can_id:03X}"
    return f"0x{traffic.can_id:03X}..0x{traffic.highest_can_id:03X}"


def _bits(rates: BusRates, data_bytes: int, *, worst_case: bool) -> str:
    """'111', or for CAN FD '30+96': bits at the nominal rate + bits at the data rate."""
    if not rates.is_fd:
        return str(frame_bits_worst_case(data_bytes) if worst_case else frame_bits_nominal(data_bytes))
    nominal, data = fd_frame_bits(data_bytes, worst_case=worst_case)
    return f"{nominal}+{data}"


def report(
    traffic: Sequence[Traffic], rate_hz: float, bitrates: Sequence[int | BusRates], out: TextIO
) -> list[BusLoad]:
    """Prints the frames of a cycle (a kind sent by several nodes in one row: 'RPDO1 x8',
    its COB-IDs, how often each of them goes) and the load per bit rate, with a WARNING line
    above 70 % and an OVERLOAD line above 100 %; returns the loads."""
    all_rates = [rate if isinstance(rate, BusRates) else BusRates(rate) for rate in bitrates]
    shown = all_rates[0]  # the frame kind whose bits the table shows (the command never mixes)
    bits_header = "bits" if not shown.is_fd else "bits (nominal+data rate)"
    frame_rows = [["frame", "COB-ID", "bytes", "per cycle", bits_header, "worst-case bits"]]
    for t in traffic:
        frame_rows.append(
            [
                t.name if t.count == 1 else f"{t.name} x{t.count}",
                _cob_ids(t),
                str(t.data_bytes),
                _format_rate(t.per_second, rate_hz),
                _bits(shown, t.data_bytes, worst_case=False),
                _bits(shown, t.data_bytes, worst_case=True),
            ]
        )
    _table(frame_rows, out)
    print(file=out)
    loads = [bus_load(traffic, rate_hz, rates) for rates in all_rates]
    load_rows = [["bit rate", "load", "worst case", "busiest cycle"]]
    for load in loads:
        load_rows.append(
            [
                load.rates.label,
                _percent(load.nominal),
                _percent(load.worst_case),
                _percent(load.peak_cycle_worst_case),
            ]
        )
    print(f"at {rate_hz:g} Hz (worst case: with worst-case bit stuffing):", file=out)
    _table(load_rows, out)
    for load in loads:
        if load.overloaded:
            print(
                f"OVERLOAD: {load.rates.label}: {_percent(load.worst_case)} of the bus (busiest cycle "
                f"{_percent(load.peak_cycle_worst_case)}) is above {_percent(FULL_LOAD)}: the exchange "
                "does not fit; lower the rate, map fewer PDOs or use a faster bus",
                file=out,
            )
        elif load.warning:
            print(
                f"WARNING: {load.rates.label}: {_percent(load.worst_case)} of the bus "
                f"(busiest cycle {_percent(load.peak_cycle_worst_case)}) is above "
                f"{_percent(WARNING_LOAD)}: lower the rate, map fewer PDOs or use a faster bus",
                file=out,
            )
    return loads
