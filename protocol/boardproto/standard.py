"""The standard blocks of every board's table: what a board.toml gets without writing it.

The CANopen engine raises the same EMCY codes, serves the same field recorder with the same
enums, and most boards share the same communication parameters; a board's table holds only its
own identity, fields, HIL I/O and PDOs, and overrides a standard block where it differs.

How a board's table and the standard one merge (`merge_standard`):
- tables ([node], [recorder]) key by key: a key the board sets replaces the standard one, the
  others stay (`[recorder] buffer_values = 1024` alone shrinks the recorder's memory);
- arrays of named tables ([[emcy]], [[enum]]) by name: a board's entry replaces the standard one
  of the same name (a whole entry, at the board's place), the standard ones it does not name
  follow the board's own, in the order below.

The recorder cannot be left out: the engine serves its objects on every board (the firmware
reads board::kRecorder), so a board short of memory shrinks it instead.
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from typing import Any

from boardproto.table import PdoDirection

STANDARD_TABLE = """\
# The communication parameters most boards share ([node]; vendor_id, product_code, revision,
# device_name, hardware_version, software_version and default_node_id are the board's own).
[node]
device_type = 0x00000000        # 0x1000: 0 = no standardised device profile
heartbeat_ms = 100              # 0x1017 producer heartbeat time
error_history_length = 8        # 0x1003 pre-defined error field: newest EMCY codes kept
heartbeat_consumers = 1         # 0x1016 consumer heartbeat time entries: the bus master's
bitrate = 1000000               # bit/s of the board's bus: the rig's timed bus in scenarios
mcu_clock_hz = 168000000        # the board's microcontroller core clock (a Cortex-M4F)
cycle_budget_percent = 50       # a control cycle's worst case may take this share of the period
period_us = 1000                # the control period [us] a run uses unless it is given another
period_us_min = 100             # the shortest control period the firmware accepts [us]
period_us_max = 1000000         # the longest control period the firmware accepts [us]
boot_ms = 20                    # after NMT reset node / reset communication, the boot-up goes
                                # out this long later (CiA 301 leaves it to the device): a real
                                # node takes tens of ms to seconds to reset (Turck's BL20 asks a
                                # master to wait 20 ms after an NMT state change, Baumueller's
                                # b maXX 1000 takes seconds). 20 ms is the short end, and long
                                # enough for a master that listens for the boot-up only after it
                                # sent the reset (python-canopen's wait_for_bootup). Counted in
                                # control cycles in lockstep, on the wall clock free-running; 0:
                                # at once. At power-on and after LSS gives the node its id the
                                # boot-up goes out at once.

# The EMCY codes the CANopen engine raises (firmware/canopen/Emcy.hpp names each).
[[emcy]]
name = "stale_sensor"
code = 0x5000
error_register = "generic"
description = "Device hardware: a sensor field was not refreshed in time (about: the field)"

[[emcy]]
name = "over_temperature"
code = 0x4210
error_register = "temperature"
description = "Device temperature: a temperature field crossed its limit (about: the field)"

[[emcy]]
name = "receive_overrun"
code = 0x8110
error_register = "communication"
description = "CAN overrun: received frames were lost (about: what was lost, e.g. the RPDO's 0x1400+n)"

[[emcy]]
name = "bus_off"
code = 0x8140
error_register = "communication"
description = "Recovered from bus off: the CAN controller went bus-off and is back on the bus (about: 0)"

[[emcy]]
name = "pdo_length_error"
code = 0x8210
error_register = "communication"
description = "PDO not processed: an RPDO shorter than its mapping arrived (about: 0x1400+n)"

[[emcy]]
name = "rpdo_timeout"
code = 0x8250
error_register = "communication"
description = "RPDO deadline (its event timer) missed (about: 0x1400+n)"

[[emcy]]
name = "heartbeat_error"
code = 0x8130
error_register = "communication"
description = "Life guard or heartbeat error: a heartbeat the node consumes timed out (about: 0x1016; byte 2: the lost node id)"

[[emcy]]
name = "ownership_violation"
code = 0xFF00
error_register = "manufacturer"
description = "Manufacturer specific: the board refused a write to a field the writer does not own (about: the field)"

# The field recorder the CANopen engine serves, after the HIL I/O blocks (0x3000, 0x3100).
[recorder]
index = 0x3200
channels = 8
buffer_values = 16384   # 64 KiB: 2048 cycles of 8 fields, 16384 of one

[[enum]]
name = "recorder_state"
description = "What the field recorder is doing (recorder_state object); a recording exists when done"

[[enum.values]]
name = "idle"
value = 0
description = "Not recording; writing idle stops a recording and discards it"

[[enum.values]]
name = "armed"
value = 1
description = "Sampling into the pre-trigger ring, waiting for the trigger; writing armed (re-)arms"

[[enum.values]]
name = "triggered"
value = 2
description = "The trigger fired: sampling the rest of the recording"

[[enum.values]]
name = "done"
value = 3
description = "The recording is complete and frozen until the recorder is armed again"

[[enum]]
name = "recorder_trigger"
description = "What starts a recording (recorder_trigger sub 1)"

[[enum.values]]
name = "immediate"
value = 0
description = "The first sample after arming is the trigger; no pre-trigger samples"

[[enum.values]]
name = "level"
value = 1
description = "The trigger field crosses the level in the direction of the edge"

[[enum.values]]
name = "flag"
value = 2
description = "A bit of the mask gets set (rising), cleared (falling) or either in the trigger field, e.g. a fault bit of fault_flags"

[[enum]]
name = "recorder_edge"
description = "Which way a trigger fires (recorder_trigger sub 4)"

[[enum.values]]
name = "rising"
value = 0
description = "Level: from below to at or above it; flag: a masked bit gets set"

[[enum.values]]
name = "falling"
value = 1
description = "Level: from above to at or below it; flag: a masked bit gets cleared"

[[enum.values]]
name = "either"
value = 2
description = "Rising or falling"
"""  # noqa: E501 (descriptions are one line each, as in any board.toml)
"""The standard blocks in board.toml's own format (`python -m boardproto standard` prints it)."""

STANDARD_PDO_SLOTS = 4
"""PDO slots of each direction a table gets without [pdo]: the CiA 301 pre-defined connection
set's four, or as many as the table's highest configured PDO number (its own or a profile's)."""

STANDARD_TRANSMISSION_TYPES: Mapping[PdoDirection, int] = {
    # Event driven: the node applies an RPDO when it arrives (the rig's inputs of a cycle).
    PdoDirection.RPDO: 255,
    # Synchronous, every SYNC: what the node gives the plant each lockstep cycle.
    PdoDirection.TPDO: 1,
}
"""A [[rpdo]]/[[tpdo]]'s transmission_type when it sets none."""

_MERGED_TABLES = ("node", "recorder")
_MERGED_ARRAYS = ("emcy", "enum")


def standard_document() -> dict[str, Any]:
    """STANDARD_TABLE parsed: a fresh copy each call, free to change."""
    return tomllib.loads(STANDARD_TABLE)


def merge_standard(document: Mapping[str, Any]) -> dict[str, Any]:
    """The board's document with the standard blocks merged in (the module's docstring says
    how). Values of the wrong shape are left as the board wrote them, for the loader to refuse."""
    merged = dict(document)
    standard = standard_document()
    for key in _MERGED_TABLES:
        own = document.get(key, {})
        merged[key] = {**standard[key], **own} if isinstance(own, Mapping) else own
    for key in _MERGED_ARRAYS:
        own = document.get(key, [])
        if not isinstance(own, list):
            continue
        named = {e["name"] for e in own if isinstance(e, Mapping) and isinstance(e.get("name"), str)}
        merged[key] = [*own, *(entry for entry in standard[key] if entry["name"] not in named)]
    return merged


def standard_names(key: str) -> frozenset[str]:
    """Names of the standard [[emcy]] or [[enum]] entries (`key` is "emcy" or "enum")."""
    return frozenset(entry["name"] for entry in standard_document()[key])


def pdo_slots(document: Mapping[str, Any], direction: PdoDirection) -> int:
    """STANDARD_PDO_SLOTS, or the highest PDO number of `direction` the document configures in
    its own [[rpdo]]/[[tpdo]] or a [[pdo_profile]]'s, whichever is more."""
    configured = [document.get(direction.value, [])]
    profiles = document.get("pdo_profile", [])
    if isinstance(profiles, list):
        configured += [p.get(direction.value, []) for p in profiles if isinstance(p, Mapping)]
    numbers = [
        entry["number"]
        for pdos in configured
        if isinstance(pdos, list)
        for entry in pdos
        if isinstance(entry, Mapping) and type(entry.get("number")) is int
    ]
    return max([STANDARD_PDO_SLOTS, *numbers])
