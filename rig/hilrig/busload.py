"""Bus load of the lockstep exchange on a real classic CAN bus ("will my trace mapping fit?").

The virtual bus has no bit rate; a real one does. For a PDO layout (`boardproto.load_table`)
and a control-cycle rate this module counts the frames of each cycle and the share of a
125 k / 250 k / 500 k / 1 Mbit/s bus they take, nominal and with worst-case bit stuffing::

    hilrig bus-load --rate-hz 1000 --bitrate 500000 --table protocol/board.toml

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

What one lockstep cycle puts on the bus (`lockstep_traffic`):
  * every enabled RPDO that maps something: the rig sends each of them every cycle;
  * SYNC with its 1-byte counter, every cycle;
  * each enabled TPDO by transmission type: n in 1..240 every n-th SYNC; 0 (acyclic
    synchronous) counted as every SYNC (the worst case: values change every cycle); 254/255
    (event driven) at most once per cycle (the board changes once per cycle), limited by the
    inhibit time, and at least at the event-timer rate;
  * the node's heartbeat (1 byte) every heartbeat_ms, independent of the cycle.

Bus load = bits per second / bit rate, averaged over time. The peak cycle (every synchronous
TPDO due at once) must also fit in one cycle period: that share is reported beside it.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from boardproto import BoardTable, Pdo, TableError, load_table
from boardproto.cia301 import SYNC_COB_ID, heartbeat_cob_id

STANDARD_BITRATES: tuple[int, ...] = (125_000, 250_000, 500_000, 1_000_000)
"""Classic CAN bit rates the command reports by default, in bit/s."""

WARNING_LOAD = 0.70
"""Above this share of the bus (worst-case stuffing) the command prints a WARNING line."""

DEFAULT_RATE_HZ = 1000.0
SYNC_DATA_BYTES = 1  # the SYNC counter
HEARTBEAT_DATA_BYTES = 1
MAX_DATA_BYTES = 8

_FIXED_BITS = 47  # every bit of a 2.0A data frame except the data field
_STUFFABLE_FIXED_BITS = 34  # SOF .. CRC without the data field
_EVENT_DRIVEN_TYPES = (254, 255)


def _check_data_bytes(data_bytes: int) -> None:
    if not 0 <= data_bytes <= MAX_DATA_BYTES:
        raise ValueError(f"a classic CAN frame carries 0..8 data bytes, got {data_bytes}")


def frame_bits_nominal(data_bytes: int) -> int:
    """Bits of a classic CAN 2.0A data frame with `data_bytes` bytes, no stuff bits, including
    the 3-bit intermission before the next frame: 47 + 8n."""
    _check_data_bytes(data_bytes)
    return _FIXED_BITS + 8 * data_bytes


def stuff_bits_worst_case(data_bytes: int) -> int:
    """Largest number of stuff bits in such a frame: floor((34 + 8n - 1) / 4)."""
    _check_data_bytes(data_bytes)
    return (_STUFFABLE_FIXED_BITS + 8 * data_bytes - 1) // 4


def frame_bits_worst_case(data_bytes: int) -> int:
    """Nominal bits plus the worst-case stuff bits: 47 + 8n + floor((34 + 8n - 1) / 4)."""
    return frame_bits_nominal(data_bytes) + stuff_bits_worst_case(data_bytes)


@dataclass(frozen=True)
class Traffic:
    """One periodic frame on the bus."""

    name: str  # "RPDO1", "SYNC", "TPDO8", "heartbeat"
    can_id: int
    data_bytes: int
    per_second: float  # average frames per second
    in_peak_cycle: bool  # sent in the cycle where every synchronous TPDO is due

    @property
    def bits_nominal(self) -> int:
        return frame_bits_nominal(self.data_bytes)

    @property
    def bits_worst_case(self) -> int:
        return frame_bits_worst_case(self.data_bytes)


@dataclass(frozen=True)
class BusLoad:
    """Share of one bus (1.0 = 100 %) the traffic takes at `bitrate`."""

    bitrate: int  # bit/s
    nominal: float  # average, no stuff bits
    worst_case: float  # average, worst-case stuffing
    peak_cycle_worst_case: float  # the busiest cycle's bits / (bitrate * cycle period)

    @property
    def warning(self) -> bool:
        return self.worst_case > WARNING_LOAD or self.peak_cycle_worst_case > WARNING_LOAD


def _check_rate(rate_hz: float) -> None:
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"the cycle rate must be a positive number of Hz, got {rate_hz}")


def bus_load(traffic: Iterable[Traffic], rate_hz: float, bitrate: int) -> BusLoad:
    """Average and peak-cycle share of a `bitrate` bus taken by `traffic` at `rate_hz` cycles/s."""
    _check_rate(rate_hz)
    if bitrate <= 0:
        raise ValueError(f"the bit rate must be positive, got {bitrate}")
    items = list(traffic)
    nominal = sum(t.per_second * t.bits_nominal for t in items)
    worst = sum(t.per_second * t.bits_worst_case for t in items)
    peak_bits = sum(t.bits_worst_case for t in items if t.in_peak_cycle)
    return BusLoad(
        bitrate=bitrate,
        nominal=nominal / bitrate,
        worst_case=worst / bitrate,
        peak_cycle_worst_case=peak_bits * rate_hz / bitrate,
    )


def _tpdo_per_second(pdo: Pdo, rate_hz: float) -> float:
    kind = pdo.transmission_type
    if kind == 0:
        return rate_hz  # acyclic synchronous: worst case, a change every cycle
    if kind <= 240:
        return rate_hz / kind
    if kind in _EVENT_DRIVEN_TYPES:
        per_second = rate_hz  # a change at most once per control cycle
        if pdo.inhibit_time_100us:
            per_second = min(per_second, 10_000 / pdo.inhibit_time_100us)
        if pdo.event_timer_ms:
            per_second = max(per_second, 1000 / pdo.event_timer_ms)
        return per_second
    raise ValueError(f"{pdo.name}: transmission type {kind} is not supported")


def lockstep_traffic(table: BoardTable, rate_hz: float, node_id: int | None = None) -> list[Traffic]:
    """The frames of the lockstep exchange for the table's default PDO layout (see the module
    docstring for what counts and how often)."""
    _check_rate(rate_hz)
    node = table.node.default_node_id if node_id is None else node_id
    traffic: list[Traffic] = []
    for pdo in table.rpdos:
        if pdo.enabled and pdo.entries:
            traffic.append(Traffic(pdo.name, pdo.cob_id(node), pdo.length_bytes, rate_hz, True))
    traffic.append(Traffic("SYNC", SYNC_COB_ID, SYNC_DATA_BYTES, rate_hz, True))
    for pdo in table.tpdos:
        if pdo.enabled and pdo.entries:
            # In the busiest cycle every synchronous TPDO is due at once (and an event-driven
            # one may fire too).
            per_second = _tpdo_per_second(pdo, rate_hz)
            traffic.append(Traffic(pdo.name, pdo.cob_id(node), pdo.length_bytes, per_second, True))
    if table.node.heartbeat_ms:
        traffic.append(
            Traffic(
                "heartbeat",
                heartbeat_cob_id(node),
                HEARTBEAT_DATA_BYTES,
                1000 / table.node.heartbeat_ms,
                True,  # it can fall into the busiest cycle too
            )
        )
    return traffic


# --- command line -----------------------------------------------------------------------------

BUS_LOAD_HELP = "share of a real CAN bus the lockstep exchange takes (no bus needed)"
BUS_LOAD_DESCRIPTION = __doc__.split("\n\n")[0] if __doc__ else BUS_LOAD_HELP


def _bitrate(text: str) -> int:
    """'500000', '500k', '1M' -> bit/s."""
    scale = {"k": 1_000, "m": 1_000_000}.get(text[-1:].lower(), 1)
    digits = text[:-1] if scale != 1 else text
    try:
        value = float(digits) * scale
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected a bit rate like 500000, 500k or 1M, got {text!r}"
        ) from None
    if not (math.isfinite(value) and value > 0 and value == int(value)):
        raise argparse.ArgumentTypeError(f"expected a positive bit rate in bit/s, got {text!r}")
    return int(value)


def _rate(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a cycle rate in Hz like 1000, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive cycle rate in Hz, got {text!r}")
    return value


def _node_id(text: str) -> int:
    try:
        value = int(text, 0)
    except ValueError:
        value = 0
    if not 1 <= value <= 127:
        raise argparse.ArgumentTypeError(f"expected a node id 1..127 (e.g. 16 or 0x10), got {text!r}")
    return value


def _default_table() -> Path:
    from hilrig.table import DEFAULT_TABLE_PATH  # the checkout's protocol/board.toml

    return DEFAULT_TABLE_PATH


def configure_bus_load_parser(parser: argparse.ArgumentParser) -> None:
    """Adds the options of `bus-load` to `parser` (usable as `Command.configure`)."""
    parser.add_argument(
        "--rate-hz", type=_rate, default=DEFAULT_RATE_HZ, help="control-cycle (SYNC) rate (default 1000)"
    )
    parser.add_argument(
        "--bitrate",
        type=_bitrate,
        action="append",
        help="bus bit rate, e.g. 500000 or 500k; repeat for several (default: 125k 250k 500k 1M)",
    )
    parser.add_argument(
        "--table", type=Path, default=None, help="field table (default: protocol/board.toml of the checkout)"
    )
    parser.add_argument(
        "--node-id", type=_node_id, default=None, help="node id for the COB-IDs shown (default: the table's)"
    )


def add_bus_load_command(
    subparsers: argparse._SubParsersAction[argparse.ArgumentParser],
) -> argparse.ArgumentParser:
    """Registers `bus-load` on an argparse sub-command set; `args.run(args)` then runs it."""
    parser = subparsers.add_parser(
        "bus-load",
        help=BUS_LOAD_HELP,
        description=BUS_LOAD_DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    configure_bus_load_parser(parser)
    parser.set_defaults(run=run_bus_load)
    return parser


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


def report(traffic: Sequence[Traffic], rate_hz: float, bitrates: Sequence[int], out: TextIO) -> list[BusLoad]:
    """Prints the frames of a cycle and the load per bit rate, with WARNING lines; returns the loads."""
    frame_rows = [["frame", "COB-ID", "bytes", "per cycle", "bits", "worst-case bits"]]
    for t in traffic:
        frame_rows.append(
            [
                t.name,
                f"0x{t.can_id:03X}",
                str(t.data_bytes),
                _format_rate(t.per_second, rate_hz),
                str(t.bits_nominal),
                str(t.bits_worst_case),
            ]
        )
    _table(frame_rows, out)
    print(file=out)
    loads = [bus_load(traffic, rate_hz, bitrate) for bitrate in bitrates]
    load_rows = [["bit rate", "load", "worst case", "busiest cycle"]]
    for load in loads:
        load_rows.append(
            [
                _bitrate_label(load.bitrate),
                _percent(load.nominal),
                _percent(load.worst_case),
                _percent(load.peak_cycle_worst_case),
            ]
        )
    print(f"at {rate_hz:g} Hz (worst case: with worst-case bit stuffing):", file=out)
    _table(load_rows, out)
    for load in loads:
        if load.warning:
            print(
                f"WARNING: {_bitrate_label(load.bitrate)}: {_percent(load.worst_case)} of the bus "
                f"(busiest cycle {_percent(load.peak_cycle_worst_case)}) is above "
                f"{_percent(WARNING_LOAD)}: lower the rate, map fewer PDOs or use a faster bus",
                file=out,
            )
    return loads


def run_bus_load(args: argparse.Namespace) -> int:
    """`hilrig bus-load`: 0 printed (a WARNING line is not a failure), 1 the table is unusable."""
    path: Path = args.table if args.table is not None else _default_table()
    try:
        table = load_table(path)
    except TableError as error:
        print(f"bus-load: {error}", file=sys.stderr)
        return 1
    bitrates = args.bitrate or list(STANDARD_BITRATES)
    traffic = lockstep_traffic(table, args.rate_hz, args.node_id)
    print(f"bus load of the lockstep exchange, table {path}", file=sys.stdout)
    report(traffic, args.rate_hz, bitrates, sys.stdout)
    return 0
