"""The CiA 305 rules (Layer Setting Services, LSS) the firmware's LSS slave and the rig's LSS
master both follow: the two COB-IDs, the command specifiers, the LSS states, the answers' error
codes, fastscan's special values and the bit timing table.

One home, as `boardproto.cia301` is for CiA 301: the rig imports this module, and the firmware
includes `board/cia305.hpp`, which `boardproto.cia305_header` generates from it.

    LssCommand.CONFIGURE_NODE_ID          # 0x11
    BIT_TIMING_KBITS[2]                   # 500
    fastscan_frame(0x12, 31, 3, 3)        # one fastscan request's 8 data bytes
"""

from __future__ import annotations

import enum
import struct

MASTER_COB_ID = 0x7E5
"""Master -> slaves: every LSS request."""
SLAVE_COB_ID = 0x7E4
"""Slave -> master: every LSS answer."""
FRAME_BYTES = 8
"""LSS frames always carry 8 bytes; unused ones are 0 (a shorter request is dropped)."""

NODE_ID_UNCONFIGURED = 0xFF
"""The node id of a node that has none yet (CiA 305): it serves LSS only, sends no boot-up and
takes part in no NMT until a node id is configured."""


class LssState(enum.IntEnum):
    """The LSS slave's two states; the values are switch state global's mode byte."""

    WAITING = 0x00
    CONFIGURATION = 0x01


class LssCommand(enum.IntEnum):
    """Command specifiers (byte 0 of every LSS frame, both directions)."""

    SWITCH_STATE_GLOBAL = 0x04
    CONFIGURE_NODE_ID = 0x11
    CONFIGURE_BIT_TIMING = 0x13
    ACTIVATE_BIT_TIMING = 0x15
    STORE_CONFIGURATION = 0x17
    SWITCH_STATE_SELECTIVE_VENDOR_ID = 0x40
    SWITCH_STATE_SELECTIVE_PRODUCT_CODE = 0x41
    SWITCH_STATE_SELECTIVE_REVISION = 0x42
    SWITCH_STATE_SELECTIVE_SERIAL = 0x43
    SWITCH_STATE_SELECTIVE_RESPONSE = 0x44  # slave -> master
    IDENTIFY_REMOTE_VENDOR_ID = 0x46
    IDENTIFY_REMOTE_PRODUCT_CODE = 0x47
    IDENTIFY_REMOTE_REVISION_LOW = 0x48
    IDENTIFY_REMOTE_REVISION_HIGH = 0x49
    IDENTIFY_REMOTE_SERIAL_LOW = 0x4A
    IDENTIFY_REMOTE_SERIAL_HIGH = 0x4B
    IDENTIFY_NON_CONFIGURED_REMOTE = 0x4C
    IDENTIFY_SLAVE = 0x4F  # slave -> master: answer to identify remote slave and fastscan
    IDENTIFY_NON_CONFIGURED_SLAVE = 0x50  # slave -> master
    FASTSCAN = 0x51
    INQUIRE_VENDOR_ID = 0x5A
    INQUIRE_PRODUCT_CODE = 0x5B
    INQUIRE_REVISION = 0x5C
    INQUIRE_SERIAL = 0x5D
    INQUIRE_NODE_ID = 0x5E


class LssError(enum.IntEnum):
    """Byte 1 of the answers to configure node-id, configure bit timing and store configuration:
    0 success, 1 refused (node id out of range, bit timing not supported, storing not supported),
    2 storage failed (store only), 0xFF implementation-specific (then byte 2 says which)."""

    SUCCESS = 0
    REFUSED = 1
    STORAGE_FAILED = 2
    SPECIFIC = 0xFF


FASTSCAN_CONFIRM = 0x80
"""Fastscan's bit-check value that resets every non-configured slave's scan (all of them
answer); 0..31 check the bits from that one up."""
FASTSCAN_HIGHEST_BIT = 31
IDENTITY_PARTS = 4
"""Fastscan's LSS sub / next: 0 vendor id, 1 product code, 2 revision, 3 serial number (the
sub-indexes 1..4 of 0x1018)."""

BIT_TIMING_STANDARD_TABLE = 0
"""Configure bit timing's table selector of the CiA 301 table below (1..127 reserved, 128..255
the manufacturer's)."""
BIT_TIMING_KBITS: dict[int, int] = {0: 1000, 1: 800, 2: 500, 3: 250, 4: 125, 6: 50, 7: 20, 8: 10}
"""The CiA 301 bit timing table: index -> kbit/s (index 5 is reserved, 9 is automatic bit rate
detection, which the firmware does not do)."""


def fastscan_frame(id_number: int, bit_check: int, sub: int, next_sub: int) -> bytes:
    """The 8 data bytes of one fastscan request: the identity part scanned so far, which bit
    (31..0, or FASTSCAN_CONFIRM), which part it is of, and which part the slave scans next when
    it matches. A slave whose part agrees from `bit_check` up answers IDENTIFY_SLAVE; with bit 0
    of the last part (next < sub) it also enters the configuration state."""
    return struct.pack("<BIBBB", LssCommand.FASTSCAN, id_number, bit_check, sub, next_sub)


def command_frame(command: LssCommand, *data: int) -> bytes:
    """An LSS request of `command` with these data bytes, zero-padded to FRAME_BYTES."""
    return bytes([command, *data]).ljust(FRAME_BYTES, b"\0")


def u32_frame(command: LssCommand, value: int) -> bytes:
    """An LSS request carrying one UNSIGNED32 (switch state selective, identify remote slave)."""
    return struct.pack("<BI", command, value).ljust(FRAME_BYTES, b"\0")


__all__ = [
    "BIT_TIMING_KBITS",
    "BIT_TIMING_STANDARD_TABLE",
    "FASTSCAN_CONFIRM",
    "FASTSCAN_HIGHEST_BIT",
    "FRAME_BYTES",
    "IDENTITY_PARTS",
    "MASTER_COB_ID",
    "NODE_ID_UNCONFIGURED",
    "SLAVE_COB_ID",
    "LssCommand",
    "LssError",
    "LssState",
    "command_frame",
    "fastscan_frame",
    "u32_frame",
]
