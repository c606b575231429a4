"""The bytes of the recorder's DOMAIN (recorder_data): one recording, self-describing.

The firmware writes it (its offsets come from the generated header, made from `HEADER_FIELDS`
here) and the host reads it with `decode_recording`. Little-endian throughout:

    offset  type          what
     0      UNSIGNED8     layout version (LAYOUT_VERSION)
     1      UNSIGNED8     channels N (0 when idle: nothing recorded)
     2      UNSIGNED16    header bytes H: where sample 0 starts (FIXED_HEADER_BYTES + 2 N,
                          rounded up to a multiple of 4)
     4      UNSIGNED16    sample divider: one sample every n-th control cycle
     6      UNSIGNED16    reserved, 0
     8      UNSIGNED32    samples S
    12      UNSIGNED32    trigger sample: index (0..S-1) of the sample the trigger fired at
    16      UNSIGNED32    cycle of sample 0 (the firmware's control cycle number)
    20      UNSIGNED32    cycle of the trigger sample (as measured)
    24      UNSIGNED32    cycle of the last sample (as measured)
    28      UNSIGNED16[N] the channels' field object indices, in channel order
     H      REAL32[S][N]  the samples, oldest first; each sample's channels in channel order

Sample k was taken at cycle `first_cycle + k * divider`. The firmware counts the divider in
control cycles run; a free-running firmware that skipped periods (overruns advance the cycle
number by more than one) breaks that grid, which `periods_skipped` detects from the two measured
cycles.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass

LAYOUT_VERSION = 1

# (name, offset, C++ type) of the fixed header; the generated header names them k<Name>Offset.
HEADER_FIELDS: tuple[tuple[str, int, str], ...] = (
    ("version", 0, "std::uint8_t"),
    ("channel_count", 1, "std::uint8_t"),
    ("header_bytes", 2, "std::uint16_t"),
    ("divider", 4, "std::uint16_t"),
    ("reserved", 6, "std::uint16_t"),
    ("sample_count", 8, "std::uint32_t"),
    ("trigger_sample", 12, "std::uint32_t"),
    ("first_cycle", 16, "std::uint32_t"),
    ("trigger_cycle", 20, "std::uint32_t"),
    ("last_cycle", 24, "std::uint32_t"),
    ("channels", 28, "std::uint16_t"),  # the first of N
)
_FIXED = struct.Struct("<BBHHHIIIII")
FIXED_HEADER_BYTES = _FIXED.size
assert HEADER_FIELDS[-1][1] == FIXED_HEADER_BYTES
CYCLE_MODULUS = 1 << 32  # the firmware's cycle number is an UNSIGNED32 that wraps


class RecordingError(ValueError):
    """The bytes are not a recording this layout describes; the message says why."""


def header_bytes(channels: int) -> int:
    """Where sample 0 starts for `channels` channels."""
    return (FIXED_HEADER_BYTES + 2 * channels + 3) // 4 * 4


def recording_bytes(channels: int, samples: int) -> int:
    """The DOMAIN's size for a recording of `samples` samples of `channels` channels."""
    return header_bytes(channels) + 4 * channels * samples


@dataclass(frozen=True)
class Recording:
    """One decoded recording: `samples[k][c]` is channel c's value at sample k."""

    channels: tuple[int, ...]  # the field object indices, in channel order
    divider: int
    trigger_sample: int
    first_cycle: int
    trigger_cycle: int
    last_cycle: int
    samples: tuple[tuple[float, ...], ...]

    @property
    def sample_count(self) -> int:
        return len(self.samples)

    def cycle_of(self, sample: int) -> int:
        """The control cycle sample `sample` was taken at (on the divider's grid)."""
        return (self.first_cycle + sample * self.divider) % CYCLE_MODULUS

    @property
    def cycles(self) -> tuple[int, ...]:
        return tuple(self.cycle_of(k) for k in range(self.sample_count))

    def column(self, channel: int) -> tuple[float, ...]:
        """One channel's values, oldest first."""
        return tuple(row[channel] for row in self.samples)

    @property
    def periods_skipped(self) -> bool:
        """True when the measured cycles are off the divider's grid: the firmware skipped
        periods (a free-running overrun) while recording, so cycle_of() is approximate."""
        if not self.samples:
            return False
        return (
            self.cycle_of(self.trigger_sample) != self.trigger_cycle
            or self.cycle_of(self.sample_count - 1) != self.last_cycle
        )


def decode_recording(data: bytes | bytearray | memoryview) -> Recording:
    """The recording in the bytes of recorder_data; RecordingError when they are not one."""
    data = bytes(data)
    if len(data) < FIXED_HEADER_BYTES:
        raise RecordingError(f"{len(data)} bytes: shorter than the {FIXED_HEADER_BYTES}-byte header")
    (version, channels, header, divider, _reserved, samples, trigger, first, trigger_cycle, last) = (
        _FIXED.unpack_from(data)
    )
    if version != LAYOUT_VERSION:
        raise RecordingError(f"layout version {version}, this decoder reads {LAYOUT_VERSION}")
    if header != header_bytes(channels):
        raise RecordingError(
            f"header of {header} bytes for {channels} channels, expected {header_bytes(channels)}"
        )
    expected = recording_bytes(channels, samples)
    if len(data) != expected:
        raise RecordingError(
            f"{len(data)} bytes, but {samples} samples of {channels} channels take {expected}"
        )
    if samples and (channels == 0 or trigger >= samples):
        raise RecordingError(f"trigger sample {trigger} outside 0..{samples - 1} or no channels")
    if samples and divider == 0:
        raise RecordingError("sample divider 0")
    indices = struct.unpack_from(f"<{channels}H", data, FIXED_HEADER_BYTES)
    rows = tuple(struct.iter_unpack(f"<{channels}f", data[header:])) if channels else ()
    return Recording(
        channels=indices,
        divider=divider,
        trigger_sample=trigger,
        first_cycle=first,
        trigger_cycle=trigger_cycle,
        last_cycle=last,
        samples=rows,
    )


def encode_recording(recording: Recording) -> bytes:
    """The DOMAIN's bytes for `recording`: what the firmware sends (for tests and fakes)."""
    channels = len(recording.channels)
    header = header_bytes(channels)
    fixed = _FIXED.pack(
        LAYOUT_VERSION,
        channels,
        header,
        recording.divider,
        0,
        recording.sample_count,
        recording.trigger_sample,
        recording.first_cycle,
        recording.trigger_cycle,
        recording.last_cycle,
    )
    indices = struct.pack(f"<{channels}H", *recording.channels)
    padding = bytes(header - len(fixed) - len(indices))
    rows: Sequence[tuple[float, ...]] = recording.samples
    body = b"".join(struct.pack(f"<{channels}f", *row) for row in rows)
    return fixed + indices + padding + body
