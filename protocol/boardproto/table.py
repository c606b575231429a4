"""The parsed board table: frozen dataclasses the generators and the rig read.

Nothing here parses TOML; `boardproto.loader.load_table` builds these objects and
guarantees their invariants (unique names and indices, ranges, PDO sizes).
"""

from __future__ import annotations

import dataclasses
import difflib
import enum
import functools
import math
from collections.abc import Iterable
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import TypeVar

from boardproto.cia301 import FunctionCode

_T = TypeVar("_T")

FIELD_BITS = 32  # a board field is a REAL32 unless its table entry names an integer type


class Kind(enum.StrEnum):
    """Component kind that writes a field; values are the spelling in board.toml."""

    SENSOR = "sensor"
    VIRTUAL_SENSOR = "virtual_sensor"
    MODULE = "module"
    ACTUATOR = "actuator"
    COMMAND = "command"
    PARAMETER = "parameter"

    @property
    def cpp_name(self) -> str:
        return "".join(part.capitalize() for part in self.value.split("_"))

    @property
    def bus_writable(self) -> bool:
        """Commands and parameters are owned by the CANopen node; the rest by firmware."""
        return self in (Kind.COMMAND, Kind.PARAMETER)


class Access(enum.StrEnum):
    """Access over the bus; values are the spelling in board.toml and in the EDS."""

    READ_ONLY = "ro"
    READ_WRITE = "rw"

    @property
    def cpp_name(self) -> str:
        return "ReadOnly" if self is Access.READ_ONLY else "ReadWrite"


class DataType(enum.IntEnum):
    """CiA 301 data types the board uses; values ARE the CiA 301 data type codes."""

    BOOLEAN = 0x0001
    INTEGER8 = 0x0002
    INTEGER16 = 0x0003
    INTEGER32 = 0x0004
    UNSIGNED8 = 0x0005
    UNSIGNED16 = 0x0006
    UNSIGNED32 = 0x0007
    REAL32 = 0x0008
    VISIBLE_STRING = 0x0009
    DOMAIN = 0x000F  # application data of any length (the recorder's buffer)

    @property
    def toml_name(self) -> str:
        return self.name.lower()

    @property
    def cpp_name(self) -> str:
        return "".join(part.capitalize() for part in self.name.split("_"))

    @property
    def bits(self) -> int:
        return _BITS[self]

    @property
    def struct_code(self) -> str:
        """Its `struct` code (little-endian, as on the bus); ValueError for a type of no fixed
        size (VISIBLE_STRING, DOMAIN)."""
        code = _STRUCT_CODES.get(self)
        if code is None:
            raise ValueError(f"{self.toml_name} has no fixed-size binary form")
        return code

    @property
    def is_signed(self) -> bool:
        return self in (DataType.INTEGER8, DataType.INTEGER16, DataType.INTEGER32)

    @property
    def integer_range(self) -> tuple[int, int]:
        """Smallest and largest value of an integer type (BOOLEAN is 0..1)."""
        if self is DataType.BOOLEAN:
            return 0, 1
        if self.is_signed:
            return -(1 << (self.bits - 1)), (1 << (self.bits - 1)) - 1
        return 0, (1 << self.bits) - 1


_BITS = {
    DataType.BOOLEAN: 1,
    DataType.INTEGER8: 8,
    DataType.INTEGER16: 16,
    DataType.INTEGER32: 32,
    DataType.UNSIGNED8: 8,
    DataType.UNSIGNED16: 16,
    DataType.UNSIGNED32: 32,
    DataType.REAL32: 32,
    DataType.VISIBLE_STRING: 0,
    DataType.DOMAIN: 0,
}

_STRUCT_CODES = {
    DataType.BOOLEAN: "?",
    DataType.INTEGER8: "b",
    DataType.INTEGER16: "h",
    DataType.INTEGER32: "i",
    DataType.UNSIGNED8: "B",
    DataType.UNSIGNED16: "H",
    DataType.UNSIGNED32: "I",
    DataType.REAL32: "f",
}

# Integer types a HIL I/O object may have (what real hardware registers give).
HIL_IO_TYPES = (
    DataType.BOOLEAN,
    DataType.INTEGER8,
    DataType.INTEGER16,
    DataType.INTEGER32,
    DataType.UNSIGNED8,
    DataType.UNSIGNED16,
    DataType.UNSIGNED32,
)


@dataclass(frozen=True)
class Field:
    """A board field: an object at (index, 0), REAL32 in the manufacturer range; a member of an
    [[array]] sits at (index, subindex 1..n) instead.

    A field of a device profile (CiA 402's controlword, targets, actuals at 0x6000..) travels as
    the integer type the profile gives it (`data_type`); the board holds its value as a float all
    the same, exact because its range stays within +-2**24.
    """

    name: str
    index: int
    unit: str
    kind: Kind
    access: Access
    min: float
    max: float
    default: float
    stored: bool
    description: str
    values: str | None = None  # the [[enum]] or [[bitset]] its values come from
    stream: bool = False
    """In the setpoint stream: a master sends it every cycle (a command's watchdog may watch it)."""
    data_type: DataType = DataType.REAL32  # on the bus; an integer type for a profile object
    subindex: int = 0
    """0 for a plain object; 1..n for the n-th member of the [[array]] at its index."""

    @property
    def bits(self) -> int:
        return self.data_type.bits


@dataclass(frozen=True)
class FieldArray:
    """A CiA 301 ARRAY of board fields at one index ([[array]] in board.toml, e.g. CiA 402's
    0x607D software position limit): sub 0 the number of members (UNSIGNED8, read-only), sub
    1..n the fields whose `subindex` is 1..n, all of one data type."""

    name: str
    index: int
    description: str
    members: tuple[str, ...]  # the member fields' names, sub-index 1..n in order

    @property
    def count(self) -> int:
        """Sub 0's value: the highest sub-index."""
        return len(self.members)


class IoDirection(enum.StrEnum):
    INPUT = "input"  # raw sensor value the rig injects (RPDO), bus-writable
    OUTPUT = "output"  # raw actuator value the firmware sends (TPDO), read-only


@dataclass(frozen=True)
class HilIo:
    """A hardware-in-the-loop I/O object: a raw driver register, not a board field."""

    name: str
    index: int
    data_type: DataType
    min: int
    max: int
    unit: str
    description: str
    direction: IoDirection
    values: str | None = None  # the [[enum]] or [[bitset]] its values come from

    subindex = 0

    @property
    def bits(self) -> int:
        return self.data_type.bits

    @property
    def access(self) -> Access:
        return Access.READ_WRITE if self.direction is IoDirection.INPUT else Access.READ_ONLY


ObjectEntry = Field | HilIo


class RecorderObject(enum.IntEnum):
    """The recorder's objects: each at the recorder's `index` plus this offset."""

    STATE = 0  # UNSIGNED8 rw, a recorder_state value: write armed to (re-)arm, idle to stop
    CHANNELS = 1  # ARRAY: sub 0 channels in use (UNSIGNED8 rw), sub n the n-th field's index
    DIVIDER = 2  # UNSIGNED16 rw: one sample every n-th control cycle
    SAMPLES = 3  # UNSIGNED32 rw: samples per recording
    TRIGGER = 4  # RECORD rw, sub-indices in RecorderTriggerSub
    STATUS = 5  # RECORD ro, sub-indices in RecorderStatusSub
    DATA = 6  # DOMAIN ro: the recording (boardproto.recording describes its bytes)

    @property
    def object_name(self) -> str:
        """recorder_state, recorder_channels...: the object's name in the EDS."""
        return f"recorder_{self.name.lower()}"


class RecorderTriggerSub(enum.IntEnum):
    """Sub-indices of the recorder's trigger record."""

    SOURCE = 1  # UNSIGNED8, a recorder_trigger value: immediate, level or flag
    FIELD = 2  # UNSIGNED16, the watched field's object index (0 = none)
    LEVEL = 3  # REAL32, the level a `level` trigger's field crosses
    EDGE = 4  # UNSIGNED8, a recorder_edge value: rising, falling or either
    MASK = 5  # UNSIGNED32, the bits a `flag` trigger watches in its field
    PRE_TRIGGER_PERCENT = 6  # UNSIGNED8 0..100, share of the samples kept before the trigger


class RecorderStatusSub(enum.IntEnum):
    """Sub-indices of the recorder's status record (read-only)."""

    SAMPLES_TAKEN = 1  # UNSIGNED32, samples taken since armed
    SAMPLES_LEFT = 2  # UNSIGNED32, samples still to take before done (0 when idle or done)


# The [[enum]]s the recorder's objects carry, with the value names the firmware acts on.
RECORDER_ENUMS: dict[str, tuple[str, ...]] = {
    "recorder_state": ("idle", "armed", "triggered", "done"),
    "recorder_trigger": ("immediate", "level", "flag"),
    "recorder_edge": ("rising", "falling", "either"),
}


@dataclass(frozen=True)
class Recorder:
    """The on-board field recorder ([recorder] in board.toml): samples chosen fields every
    control cycle into static memory around a trigger; the host uploads the buffer."""

    index: int  # the first object; the others follow (RecorderObject)
    max_channels: int  # fields recorded at once, at most
    buffer_values: int  # REAL32 values of sample memory: samples * channels at most

    def index_of(self, recorder_object: RecorderObject) -> int:
        return self.index + recorder_object

    @property
    def indices(self) -> range:
        return range(self.index, self.index + len(RecorderObject))

    @property
    def default_samples(self) -> int:
        """The samples a recording takes until told otherwise: as many as fit at max_channels."""
        return self.buffer_values // self.max_channels


class ErrorRegisterBit(enum.IntFlag):
    """Bits of the error register 0x1001 (CiA 301, 7.5.2.2); names are the board.toml spelling."""

    GENERIC = 0x01  # set whenever any error is active
    CURRENT = 0x02
    VOLTAGE = 0x04
    TEMPERATURE = 0x08
    COMMUNICATION = 0x10
    DEVICE_PROFILE = 0x20
    MANUFACTURER = 0x80  # protocol-literal: error register bit 7, not SYNC

    @property
    def toml_name(self) -> str:
        return (self.name or "").lower()


ERROR_RESET_CODE = 0x0000
"""The EMCY code of an 'error reset or no error' frame (CiA 301)."""


def camel_case(snake: str) -> str:
    """control_mode -> ControlMode: the type name in C++ and Python."""
    return "".join(part.capitalize() for part in snake.split("_"))


@dataclass(frozen=True)
class EnumValue:
    name: str
    value: int
    description: str


@dataclass(frozen=True)
class ValueEnum:
    """A named set of values a field carries ([[enum]] in board.toml), e.g. control modes."""

    name: str
    description: str
    values: tuple[EnumValue, ...]

    @property
    def type_name(self) -> str:
        return camel_case(self.name)

    def value(self, name: str) -> EnumValue:
        return _lookup(f"{self.name} value", {v.name: v for v in self.values}, name)

    def name_of(self, number: float) -> str | None:
        """The value's name, or None for a number that is none of the values."""
        for value in self.values:
            if value.value == number:
                return value.name
        return None

    def label(self, number: float) -> str:
        """'velocity' for 1; a number that is none of the values says so: '7 (no control_mode)'."""
        return self.name_of(number) or f"{number:g} (no {self.name})"

    def python_type(self) -> type[enum.IntEnum]:
        """An IntEnum built from the table (members upper-case: ControlMode.VELOCITY)."""
        return _python_enum(self)


@dataclass(frozen=True)
class FlagBit:
    name: str
    bit: int
    description: str
    emcy: str | None  # the [[emcy]] raised when the bit latches
    about: str | None  # the object the EMCY names; None when the raiser names it at run time

    @property
    def mask(self) -> int:
        return 1 << self.bit


@dataclass(frozen=True)
class BitSet:
    """Named bits of a flags field ([[bitset]] in board.toml), e.g. the fault flags."""

    name: str
    description: str
    bits: tuple[FlagBit, ...]

    @property
    def type_name(self) -> str:
        return camel_case(self.name)

    def bit(self, name: str) -> FlagBit:
        return _lookup(f"{self.name} bit", {b.name: b for b in self.bits}, name)

    def names_of(self, flags: float) -> tuple[str, ...]:
        """Names of the bits set in `flags`, lowest first; an unnamed set bit is 'bit N'."""
        number = int(flags)
        named = {b.bit: b.name for b in self.bits}
        return tuple(named.get(n, f"bit {n}") for n in range(number.bit_length()) if number >> n & 1)

    def label(self, flags: float) -> str:
        """'motor_encoder_stale|over_temperature' for 9, 'none' for 0; a number that cannot be a
        set of bits says so: '0.5 (no fault_flags)'."""
        if not math.isfinite(flags) or flags != int(flags) or flags < 0:
            return f"{flags:g} (no {self.name})"
        return "|".join(self.names_of(flags)) or "none"

    def python_type(self) -> type[enum.IntFlag]:
        """An IntFlag built from the table (members upper-case: FaultFlags.MOTOR_ENCODER_STALE)."""
        return _python_flag(self)


@dataclass(frozen=True)
class EmcyCode:
    """An emergency code the firmware raises ([[emcy]] in board.toml)."""

    name: str
    code: int
    error_register: ErrorRegisterBit
    description: str


@functools.cache
def _python_enum(values: ValueEnum) -> type[enum.IntEnum]:
    members = {v.name.upper(): v.value for v in values.values}
    return enum.IntEnum(values.type_name, members)  # type: ignore[return-value]


@functools.cache
def _python_flag(bitset: BitSet) -> type[enum.IntFlag]:
    members = {b.name.upper(): b.mask for b in bitset.bits}
    return enum.IntFlag(bitset.type_name, members)  # type: ignore[return-value]


@dataclass(frozen=True)
class NodeIdentity:
    device_type: int
    vendor_id: int
    product_code: int
    revision: int
    device_name: str
    hardware_version: str
    software_version: str
    default_node_id: int
    heartbeat_ms: int
    error_history_length: int
    heartbeat_consumers: int
    bitrate: int
    """The bus's bit rate [bit/s]: what a lockstep run's timed bus carries (`hilrig.wire.bustime`)."""
    mcu_clock_hz: int
    cycle_budget_percent: int
    """The share of the period (at `mcu_clock_hz`) the worst control cycle may take on the
    microcontroller: what the Cortex-M build's cycle budget check holds it to."""
    period_us: int
    """The control period [us] of a run that names none: the firmware's --period-us default and
    the rig's (`hilrig.session.run`)."""
    period_us_min: int
    period_us_max: int
    """The control periods [us] the firmware accepts and the rig lets a run ask for."""
    boot_ms: int
    """How long after NMT reset node / reset communication the node sends its boot-up [ms]:
    control cycles' worth in lockstep, the wall clock free-running (0: at once)."""

    def cycle_budget(self, period_us: int) -> int:
        """Core cycles a control cycle of `period_us` may take at most."""
        return self.mcu_clock_hz * period_us * self.cycle_budget_percent // 100_000_000


class PdoDirection(enum.StrEnum):
    RPDO = "rpdo"  # received by the node
    TPDO = "tpdo"  # transmitted by the node

    @property
    def communication_index(self) -> int:
        """Index of PDO 1's communication parameter record (0x1400 / 0x1800)."""
        return 0x1400 if self is PdoDirection.RPDO else 0x1800

    @property
    def mapping_index(self) -> int:
        """Index of PDO 1's mapping parameter record (0x1600 / 0x1A00)."""
        return 0x1600 if self is PdoDirection.RPDO else 0x1A00

    @property
    def predefined_cob_id_base(self) -> int:
        """CiA 301 pre-defined connection set base of PDO 1 (0x200 / 0x180)."""
        return int(FunctionCode.RPDO1 if self is PdoDirection.RPDO else FunctionCode.TPDO1)


@dataclass(frozen=True)
class PdoEntry:
    """One mapped object of a PDO: (index, subindex, bits) plus the object's name."""

    name: str
    index: int
    subindex: int
    bits: int

    @property
    def mapping_value(self) -> int:
        """The UNSIGNED32 written to a mapping sub-index (CiA 301: index, sub, length)."""
        return (self.index << 16) | (self.subindex << 8) | self.bits


PDO_NOT_VALID = 0x8000_0000  # COB-ID bit 31: PDO disabled
# COB-ID bit 30 of a TPDO: no remote request (RTR) allowed. The node answers no RTR, so every
# TPDO says so; on an RPDO the bit is reserved and stays 0.
RTR_NOT_ALLOWED = 0x4000_0000


@dataclass(frozen=True)
class Pdo:
    """The default configuration of one PDO slot."""

    direction: PdoDirection
    number: int  # 1-based
    cob_id_base: int  # COB-ID = cob_id_base + node id
    enabled: bool
    transmission_type: int
    inhibit_time_100us: int
    event_timer_ms: int
    entries: tuple[PdoEntry, ...]
    sync_start: int = 0  # TPDO sub 6: the SYNC counter of its first transmission (0: none)

    @property
    def name(self) -> str:
        return f"{self.direction.value.upper()}{self.number}"

    @property
    def communication_index(self) -> int:
        return self.direction.communication_index + self.number - 1

    @property
    def mapping_index(self) -> int:
        return self.direction.mapping_index + self.number - 1

    @property
    def bits(self) -> int:
        return sum(entry.bits for entry in self.entries)

    @property
    def length_bytes(self) -> int:
        return (self.bits + 7) // 8

    def cob_id(self, node_id: int) -> int:
        """The 11-bit CAN identifier for node_id (without the 'not valid' bit)."""
        return self.cob_id_base + node_id

    def cob_id_value(self, node_id: int) -> int:
        """The UNSIGNED32 of communication sub-index 1: bit 31 set when disabled, bit 30 set on
        a TPDO (no RTR)."""
        return self.cob_id(node_id) | self.cob_id_flags

    @property
    def cob_id_flags(self) -> int:
        """Bits 31 (not valid) and 30 (TPDO: no RTR) of the default COB-ID."""
        rtr = RTR_NOT_ALLOWED if self.direction is PdoDirection.TPDO else 0
        return rtr | (0 if self.enabled else PDO_NOT_VALID)


FULL_PDO_PROFILE = "full"
"""The profile that is the table's own [[rpdo]]/[[tpdo]] mapping (the firmware's default)."""


@dataclass(frozen=True)
class PdoProfile:
    """Another mapping of the same PDO slots (board.toml's [[pdo_profile]]), written to a board
    over SDO (`hilrig pdo apply NAME`); `sync_counter_overflow` is 0x1019's value with it (the
    SYNC start values of its TPDOs count on the SYNC counter)."""

    name: str
    description: str
    rpdos: tuple[Pdo, ...]  # every RPDO slot, number 1..n in order
    tpdos: tuple[Pdo, ...]
    sync_counter_overflow: int = 0


class UnknownNameError(KeyError):
    """A name that the table does not define; the message lists close matches."""

    def __str__(self) -> str:  # KeyError would repr() the message
        return str(self.args[0])


def _lookup(what: str, items: dict[str, _T], name: str) -> _T:
    try:
        return items[name]
    except KeyError:
        raise UnknownNameError(unknown_name_message(what, name, items)) from None


def unknown_name_message(what: str, name: str, known: Iterable[str]) -> str:
    """'no field named 'x'; did you mean 'y'?' with up to three close matches."""
    matches = difflib.get_close_matches(name, list(known), n=3, cutoff=0.6)
    hint = f"; did you mean {' or '.join(repr(m) for m in matches)}?" if matches else ""
    return f"no {what} named {name!r}{hint}"


@dataclass(frozen=True)
class BoardTable:
    """Everything board.toml defines, validated. Look objects up by name with
    `field("motor_velocity")`, `hil_input(...)`, `hil_output(...)`, `entry(...)`;
    a typo raises UnknownNameError (a KeyError) listing the close matches."""

    source: Path
    node: NodeIdentity
    fields: tuple[Field, ...]
    hil_inputs: tuple[HilIo, ...]
    hil_outputs: tuple[HilIo, ...]
    rpdos: tuple[Pdo, ...]  # every RPDO slot, number 1..n in order
    tpdos: tuple[Pdo, ...]  # every TPDO slot, number 1..n in order
    enums: tuple[ValueEnum, ...] = ()
    bitsets: tuple[BitSet, ...] = ()
    emcy_codes: tuple[EmcyCode, ...] = ()
    recorder: Recorder | None = None
    pdo_profiles: tuple[PdoProfile, ...] = ()  # the first is FULL_PDO_PROFILE: rpdos/tpdos above
    arrays: tuple[FieldArray, ...] = ()  # the [[array]] objects, by index; members are in `fields`

    def pdo_profile(self, name: str) -> PdoProfile:
        """The [[pdo_profile]] `name`; UnknownNameError listing the close ones."""
        return _lookup("PDO profile", {p.name: p for p in self.pdo_profiles}, name)

    def with_pdo_profile(self, name: str) -> BoardTable:
        """This table with the PDO mapping of profile `name` in place of its own."""
        profile = self.pdo_profile(name)
        return dataclasses.replace(self, rpdos=profile.rpdos, tpdos=profile.tpdos)

    @cached_property
    def _fields_by_name(self) -> dict[str, Field]:
        return {f.name: f for f in self.fields}

    @cached_property
    def _entries_by_name(self) -> dict[str, ObjectEntry]:
        return {e.name: e for e in self.entries}

    @cached_property
    def _entries_by_index(self) -> dict[tuple[int, int], ObjectEntry]:
        return {(e.index, e.subindex): e for e in self.entries}

    @property
    def entries(self) -> tuple[ObjectEntry, ...]:
        """Board fields, then HIL inputs, then HIL outputs."""
        return (*self.fields, *self.hil_inputs, *self.hil_outputs)

    @property
    def field_names(self) -> tuple[str, ...]:
        return tuple(f.name for f in self.fields)

    @property
    def pdos(self) -> tuple[Pdo, ...]:
        return (*self.rpdos, *self.tpdos)

    @property
    def setpoint_stream(self) -> tuple[str, ...]:
        """The fields a master sends every cycle (`stream = true`), in table order; the rig sends
        the RPDOs that carry them each cycle. Empty: RPDOs go out when a value changes."""
        return tuple(f.name for f in self.fields if f.stream)

    def field(self, name: str) -> Field:
        return _lookup("board field", self._fields_by_name, name)

    def hil_input(self, name: str) -> HilIo:
        return _lookup("HIL input", {io.name: io for io in self.hil_inputs}, name)

    def hil_output(self, name: str) -> HilIo:
        return _lookup("HIL output", {io.name: io for io in self.hil_outputs}, name)

    def entry(self, name: str) -> ObjectEntry:
        """A board field or HIL I/O object by name."""
        return _lookup("board field or HIL I/O object", self._entries_by_name, name)

    def entry_at(self, index: int, subindex: int = 0) -> ObjectEntry:
        """The field or HIL I/O object at (index, subindex): an [[array]]'s member at 1..n."""
        try:
            return self._entries_by_index[index, subindex]
        except KeyError:
            raise UnknownNameError(f"no board object at 0x{index:04X} sub {subindex}") from None

    def array_at(self, index: int) -> FieldArray | None:
        """The [[array]] at `index`, or None where the object is a plain one (or none)."""
        return next((a for a in self.arrays if a.index == index), None)

    def fields_of_kind(self, kind: Kind) -> tuple[Field, ...]:
        return tuple(f for f in self.fields if f.kind is kind)

    def rpdo(self, number: int) -> Pdo:
        return self._pdo(self.rpdos, "RPDO", number)

    def enum(self, name: str) -> ValueEnum:
        return _lookup("enum", {e.name: e for e in self.enums}, name)

    def bitset(self, name: str) -> BitSet:
        return _lookup("bitset", {b.name: b for b in self.bitsets}, name)

    def emcy(self, name: str) -> EmcyCode:
        return _lookup("EMCY code", {e.name: e for e in self.emcy_codes}, name)

    def emcy_by_code(self, code: int) -> EmcyCode | None:
        return next((e for e in self.emcy_codes if e.code == code), None)

    def values_of(self, name: str) -> ValueEnum | BitSet | None:
        """The enum or bitset the named field or HIL I/O object carries, if it declares one."""
        self.entry(name)  # an unknown name raises, with the close matches
        return self.named_values.get(name)

    @cached_property
    def named_values(self) -> dict[str, ValueEnum | BitSet]:
        """The enum or bitset of every field and HIL I/O object that declares one, by name."""
        sets = {s.name: s for s in (*self.enums, *self.bitsets)}
        return {e.name: sets[e.values] for e in self.entries if e.values is not None}

    def tpdo(self, number: int) -> Pdo:
        return self._pdo(self.tpdos, "TPDO", number)

    @staticmethod
    def _pdo(slots: tuple[Pdo, ...], label: str, number: int) -> Pdo:
        if not 1 <= number <= len(slots):
            raise UnknownNameError(f"no {label}{number}: the node has {label}1..{len(slots)}")
        return slots[number - 1]
