"""Bits a classic CAN frame takes on the bus: the one home of that arithmetic, for the bus-load
budget from the table (`hilrig.apps.busload`, where the formulas and their source are explained),
the load measured from frames (`hilrig.apps.busstat`) and the bus load a trace plots
(`hilrig.observe.busmeter`).

    frame_bits_worst_case(8)      # 135: an 8-byte frame with worst-case bit stuffing
    frame_bits(12, worst_case=True)   # an FD frame's length counted as a classic 8-byte one
"""

from __future__ import annotations

MAX_DATA_BYTES = 8
"""Data bytes of a classic CAN frame at most."""
_FIXED_BITS = 47  # every bit of a 2.0A data frame except the data field
_STUFFABLE_FIXED_BITS = 34  # SOF .. CRC without the data field


def check_data_bytes(data_bytes: int) -> None:
    if not 0 <= data_bytes <= MAX_DATA_BYTES:
        raise ValueError(f"a classic CAN frame carries 0..8 data bytes, got {data_bytes}")


def frame_bits_nominal(data_bytes: int) -> int:
    """Bits of a classic CAN 2.0A data frame with `data_bytes` bytes, no stuff bits, including
    the 3-bit intermission before the next frame: 47 + 8n."""
    check_data_bytes(data_bytes)
    return _FIXED_BITS + 8 * data_bytes


def stuff_bits_worst_case(data_bytes: int) -> int:
    """Largest number of stuff bits in such a frame: floor((34 + 8n - 1) / 4)."""
    check_data_bytes(data_bytes)
    return (_STUFFABLE_FIXED_BITS + 8 * data_bytes - 1) // 4


def frame_bits_worst_case(data_bytes: int) -> int:
    """Nominal bits plus the worst-case stuff bits: 47 + 8n + floor((34 + 8n - 1) / 4)."""
    return frame_bits_nominal(data_bytes) + stuff_bits_worst_case(data_bytes)


def frame_bits(data_bytes: int, *, worst_case: bool) -> int:
    """A frame's bits as above; more than 8 bytes (an FD frame) counted as 8, a classic frame's
    most (the safe side is not claimed for it)."""
    n = min(data_bytes, MAX_DATA_BYTES)
    return frame_bits_worst_case(n) if worst_case else frame_bits_nominal(n)
