"""Entity paths of the rig's traces: where each board field, the plant's truth, the bus counts and
the events go in a Rerun recording. The one module of hilrig that dashboards/ imports, so views
and data cannot drift apart; it imports nothing of hilrig but the exception tree.

    /fields/<kind>s/<name>   board fields by kind: sensors, virtual_sensors, modules, actuators,
                             commands, parameters; received in TPDOs, or sent by the rig (RPDO
                             commands every cycle they go out, SDO writes when made)
    /hil/inputs/<name>       raw sensor values the rig sent (RPDO1), /hil/outputs/<name> raw
                             actuator values the node sent (motor_duty, led_pattern)
    /truth/<quantity>        the plant's ground truth (its `truth_fields`, unit in the name),
                             plus its `truth_parameters` (the joint: spring_stiffness_nm_per_rad)
    /bus/frames/<PDO>        frames of that PDO's COB-ID in each cycle (TPDO5: 1 every 10th),
                             /bus/per_cycle/{tpdos,rpdos} their sums per direction
    /bus/load                the bus load per 10 ms window [% of the bit rate]
    /bus/tpdo_delay/<TPDO>   each TPDO's delay after its SYNC [ms]
    /bus/problems/<kind>     late, missing, malformed TPDOs and error frames, counted so far
    /events/nmt, /events/emcy, /events/sdo, /events/bus    text log entries with a level
    <field or HIL path>/label  for a field whose values have names in board.toml (control_mode,
                             fault_flags, led_pattern): a text entry at each change of value,
                             "control_mode = velocity", "fault_flags = motor_encoder_stale|..."
    /modules/<node id>/...   each module of a robot, the same paths below it
    /robot/links/<k>         a robot's chain in 3D

Timelines: `cycle` (sequence) and `sim_time` (duration, exact cycle * period) in lockstep; in
real-time mode `wall_time` (timestamp) replaces `sim_time`.
"""

from __future__ import annotations

from collections.abc import Collection, Iterable
from enum import Enum
from typing import Any, Protocol

from boardproto import BoardTable, Field, IoDirection, Kind
from hilrig.errors import unknown_name


class EntryTable(Protocol):
    """What the paths need of a table (a `hilrig.table.RigTable`): the board's entries, and a
    check of names that raises FieldNameError with close matches."""

    @property
    def board(self) -> BoardTable: ...

    def check(self, names: Iterable[str]) -> None: ...


class NumberedPdo(Protocol):
    """What `frames_path` needs of a PDO (a `hilrig.wire.transport.PdoLayout`)."""

    @property
    def direction(self) -> Any: ...

    @property
    def number(self) -> int: ...


CYCLE_TIMELINE = "cycle"
SIM_TIME_TIMELINE = "sim_time"
WALL_TIME_TIMELINE = "wall_time"
FIELDS_ROOT = "/fields"
HIL_INPUTS_ROOT = "/hil/inputs"
HIL_OUTPUTS_ROOT = "/hil/outputs"
TRUTH_ROOT = "/truth"
EVENTS_ROOT = "/events"
NMT_PATH = f"{EVENTS_ROOT}/nmt"
EMCY_PATH = f"{EVENTS_ROOT}/emcy"
LABEL_CHILD = "label"
SDO_PATH = f"{EVENTS_ROOT}/sdo"
MODULES_ROOT = "/modules"
"""A robot's modules each trace under /modules/<node id>: their fields, truth and events."""
BUS_ROOT = "/bus"
"""What the driver exchanged per cycle: /bus/frames/<PDO> (frames of that COB-ID in the cycle),
/bus/per_cycle/{tpdos,rpdos} (their sums per direction); /events/bus says which PDOs the node
uses and when a TPDO is late, missing or malformed. Frame counts are step series with a row
where the count changes and at the last cycle of each batch (a missing frame is a 0 at its
cycle and the count again at the next): the value at any cycle is the latest row at or before
it."""
BUS_EVENTS_PATH = f"{EVENTS_ROOT}/bus"
"""Which PDOs the node uses; TPDOs late, missing or malformed (the driver's events)."""
BUS_FRAMES_ROOT = f"{BUS_ROOT}/frames"
BUS_LOAD_PATH = f"{BUS_ROOT}/load"
"""Bus load per 10 ms window, % of the bit rate (`hilrig.observe.busmeter`)."""
BUS_DELAY_ROOT = f"{BUS_ROOT}/tpdo_delay"
"""/bus/tpdo_delay/<TPDO label>: each TPDO's delay after its SYNC, ms."""
TIMED_BUS_ROOT = f"{BUS_ROOT}/timed"
"""A lockstep run on the timed bus (`hilrig.engine.bustiming`), per cycle: /bus/timed/load (% of
its bit rate the cycle's time was busy, at most 100: the frames' wire time), /bus/timed/backlog
(frames waiting for a later cycle after it), /bus/timed/late (frames of earlier cycles it
delivered). Nothing on the ideal bus."""
TIMED_LOAD_PATH = f"{TIMED_BUS_ROOT}/load"
TIMED_BACKLOG_PATH = f"{TIMED_BUS_ROOT}/backlog"
TIMED_LATE_PATH = f"{TIMED_BUS_ROOT}/late"
TIMED_BUS_SERIES = (TIMED_LOAD_PATH, TIMED_BACKLOG_PATH, TIMED_LATE_PATH)
"""Recorded only by a run on the timed bus: a dashboard's checks do not count them missing, or
drawing nothing, in a trace that has none of them (a run on the ideal bus)."""


def absent_on_the_ideal_bus(series: str, with_data: Collection[str]) -> bool:
    """True for a timed bus's series in a trace of a run on the ideal bus (`TIMED_BUS_SERIES`)."""
    return series in TIMED_BUS_SERIES and not any(timed in with_data for timed in TIMED_BUS_SERIES)
BUS_PROBLEMS_ROOT = f"{BUS_ROOT}/problems"
"""/bus/problems/{late,missing,malformed,error_frames}: counts so far, per load window."""


WALL_CLOCK_SERIES = (f"{BUS_DELAY_ROOT}/*",)
"""Globs of the series measured by the rig's wall clock, not by the simulation: the TPDOs' delays
differ from run to run of one seed, so `hilrig diff` leaves them out."""


class BusProblem(Enum):
    """What the bus's counts count (`hilrig.observe.busmeter`), by series name."""

    LATE = "late"
    MISSING = "missing"
    MALFORMED = "malformed"
    ERROR_FRAME = "error_frames"


def problem_path(problem: BusProblem) -> str:
    """'/bus/problems/missing': the count of that problem up to each load window."""
    return f"{BUS_PROBLEMS_ROOT}/{problem.value}"


def delay_path(label: str) -> str:
    """'/bus/tpdo_delay/TPDO1': that TPDO's delay after its SYNC [ms]."""
    return f"{BUS_DELAY_ROOT}/{label}"


BUS_TPDOS_PER_CYCLE = f"{BUS_ROOT}/per_cycle/tpdos"
BUS_RPDOS_PER_CYCLE = f"{BUS_ROOT}/per_cycle/rpdos"
ROBOT_ROOT = "/robot"
"""A robot's 3D view: /robot/links/<k> (a capsule moved by the chain's pose of link k),
/robot/ground; its own events (a module lost...) at /events/robot."""
DIFF_BASE_ROOT = "/base"
DIFF_CAND_ROOT = "/cand"
DIFF_ROOT = "/diff"
"""A comparison of two traces (`hilrig diff`): the base run's series under /base, the
candidate's under /cand, each at its own path below, and cand - base under /diff."""
GENERATED_DASHBOARD = "board"
"""The dashboard made from any board's table and plant (dashboards/board.py)."""

BOARD_PROPERTY = "board"
"""The recording property (Rerun's /__properties/board) the tracer writes at the start of every
trace: `table`, the board's table as TOML text; `table_name`, its file's name; `dashboard`, the
dashboard the trace opens with. `hilrig view` reads it to build the trace's own dashboard."""

DIFF_EVENTS_PATH = f"{DIFF_ROOT}/divergences"
"""Where a comparison says, per series, the first cycle it differs beyond the tolerance."""
TRUE_SPRING_STIFFNESS = "spring_stiffness_nm_per_rad"
"""Extra truth series: the plant's spring constant, to plot next to spring_constant_estimate.
A parameter: a step series with rows where it changes and at the last cycle of each batch."""

_TRUTH_UNITS = (  # the longest suffix first: "_nm_per_rad" also ends in "_rad"
    ("_rad_s", "rad/s"),
    ("_nm_per_rad", "N*m/rad"),
    ("_rad", "rad"),
    ("_nm", "N*m"),
    ("_a", "A"),
    ("_c", "degC"),
    ("_ohm", "ohm"),
    ("_m_s2", "m/s^2"),
    ("_v", "V"),
    ("_w", "W"),
    ("_s", "s"),
)
TRUTH_QUANTITIES: tuple[str, ...] = (
    "motor_angle_rad",
    "motor_velocity_rad_s",
    "load_angle_rad",
    "load_velocity_rad_s",
    "current_a",
    "winding_temperature_c",
    "spring_deflection_rad",
    "spring_torque_nm",
    "winding_resistance_ohm",
    "applied_duty",
    TRUE_SPRING_STIFFNESS,
)
"""The demo joint's truth series, which its dashboards name: the JointState attributes but its
time (a unit test keeps the two lists equal; the paths import no plant), and the spring
constant. Any other plant's: `plant_truth_path`."""


def kind_path(kind: Kind) -> str:
    """'/fields/virtual_sensors' for Kind.VIRTUAL_SENSOR."""
    return f"{FIELDS_ROOT}/{kind.value}s"


def field_path(field: Field) -> str:
    """'/fields/sensors/motor_position'."""
    return f"{kind_path(field.kind)}/{field.name}"



def frames_path(pdo: NumberedPdo) -> str:
    """'/bus/frames/TPDO3': frames of this PDO's COB-ID per cycle."""
    return f"{BUS_FRAMES_ROOT}/{pdo.direction.value}{pdo.number}"


def module_root(node_id: int) -> str:
    """'/modules/3': where module 3 of a robot traces (prefix of all its entity paths)."""
    return f"{MODULES_ROOT}/{node_id}"


def link_path(index: int) -> str:
    """'/robot/links/0' for the chain's first link."""
    return f"{ROBOT_ROOT}/links/{index}"


def truth_path(quantity: str) -> str:
    """'/truth/load_velocity_rad_s'; the name is checked against the JointState attributes."""
    if quantity not in TRUTH_QUANTITIES:
        raise unknown_name("ground-truth quantity", quantity, TRUTH_QUANTITIES)
    return f"{TRUTH_ROOT}/{quantity}"


def plant_truth_path(quantity: str) -> str:
    """'/truth/<quantity>' of any plant's truth quantity (`Plant.truth_fields`, or a name of
    its `truth_parameters`): the plant said the name, nothing to check it against here."""
    return f"{TRUTH_ROOT}/{quantity}"


def truth_unit(quantity: str) -> str:
    for suffix, unit in _TRUTH_UNITS:
        if quantity.endswith(suffix):
            return unit
    return "1"



def label_path(path: str) -> str:
    """Where the names of an enum or bitset entity's values go ("velocity" for control_mode 1)."""
    return f"{path}/{LABEL_CHILD}"



def entity_paths(table: EntryTable) -> dict[str, str]:
    """Entity path of every board field and HIL I/O object, by name (no Rerun import)."""
    paths: dict[str, str] = {}
    for entry in table.board.entries:
        if isinstance(entry, Field):
            paths[entry.name] = field_path(entry)
        elif entry.direction is IoDirection.INPUT:
            paths[entry.name] = f"{HIL_INPUTS_ROOT}/{entry.name}"
        else:
            paths[entry.name] = f"{HIL_OUTPUTS_ROOT}/{entry.name}"
    return paths
