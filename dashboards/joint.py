"""Rerun blueprints for the demo joint, built from the entity paths the tracer logs.

    python -m dashboards overview out/scenarios/<test>/trace.rrd       # open a trace with a view
    blueprint("tuning", RigTable.load())                               # rerun.blueprint.Blueprint

Every path comes from `hilrig.observe.paths` (and the shared view parts from `hilrig.observe.layout`),
the only modules of hilrig the dashboards import (so the rig can load them without their pulling
the rig back in); the table is given, and every field
name is checked against it when a blueprint is built, so a renamed field fails here with close
matches instead of showing an empty plot.
"""

from __future__ import annotations

from collections.abc import Callable

import rerun.blueprint as rrb

from dashboards.diff import diff
from dashboards.robot import robot
from hilrig.observe.layout import ORIGIN_SUBTREE, WHOLE_RUN
from hilrig.observe.paths import (
    BUS_DELAY_ROOT,
    BUS_EVENTS_PATH,
    BUS_LOAD_PATH,
    CYCLE_TIMELINE,
    EMCY_PATH,
    EVENTS_ROOT,
    NMT_PATH,
    SDO_PATH,
    SIM_TIME_TIMELINE,
    TIMED_BACKLOG_PATH,
    TIMED_LATE_PATH,
    TIMED_LOAD_PATH,
    TRUE_SPRING_STIFFNESS,
    BusProblem,
    EntryTable,
    entity_paths,
    problem_path,
    truth_path,
)


class Paths:
    """Field name -> entity path, checked against the table."""

    def __init__(self, table: EntryTable) -> None:
        self._table = table
        self._paths = entity_paths(table)

    def __call__(self, *names: str) -> list[str]:
        self._table.check(names)
        return [self._paths[name] for name in names]


def plot(name: str, contents: list[str] | None = None, *, origin: str = "/") -> rrb.TimeSeriesView:
    """A time series plot of `contents` (default: everything under `origin`), the whole run."""
    shown = contents if contents is not None else ORIGIN_SUBTREE
    return rrb.TimeSeriesView(name=name, origin=origin, contents=shown, axis_x=WHOLE_RUN)


def events(name: str = "Events (NMT, EMCY, SDO, bus, faults)") -> rrb.TextLogView:
    return rrb.TextLogView(name=name, origin=EVENTS_ROOT)


def blueprint_of(*parts: rrb.Container | rrb.View, timeline: str = SIM_TIME_TIMELINE) -> rrb.Blueprint:
    return rrb.Blueprint(*parts, rrb.TimePanel(timeline=timeline), collapse_panels=False)


def overview(table: EntryTable) -> rrb.Blueprint:
    """Is the joint doing what it is told? Per controlled quantity the setpoint, the firmware's
    belief and the truth on one plot (one unit per plot); the motor command it turned into; the
    mode and the fault state; the event log."""
    p = Paths(table)
    return blueprint_of(rrb.Vertical(
        rrb.Grid(
            plot("velocity [rad/s]: setpoint, firmware estimate, true",
                  [*p("velocity_setpoint", "output_velocity"), truth_path("load_velocity_rad_s")]),
            plot("torque [N*m]: setpoint, firmware estimate, true",
                  [*p("torque_setpoint", "joint_torque"), truth_path("spring_torque_nm")]),
            plot("position [rad]: setpoint, firmware estimate, true",
                  [*p("position_setpoint", "output_position"), truth_path("load_angle_rad")]),
            plot("motor duty [1]: commanded by the firmware, applied by the plant",
                  [*p("motor_duty_command"), truth_path("applied_duty")]),
            plot("control mode (velocity, torque, position...)", p("control_mode")),
            plot("fault state: fault flags, safe state, watchdog",
                  p("fault_flags", "safe_state", "watchdog_tripped")),
        ),
        events(),
        row_shares=[4, 1],
    ))


def tuning(table: EntryTable) -> rrb.Blueprint:
    """Controller tuning: per loop, setpoint vs measurement vs truth, and the controller's
    effort (one unit per plot)."""
    p = Paths(table)
    return blueprint_of(rrb.Vertical(
        rrb.Horizontal(
            plot("velocity loop [rad/s]: setpoint, measurement, true",
                  [*p("velocity_setpoint", "output_velocity"), truth_path("load_velocity_rad_s")]),
            plot("velocity loop effort [1]: controller output, duty",
                  p("velocity_controller_output", "motor_duty_command")),
        ),
        rrb.Horizontal(
            plot("torque loop [N*m]: setpoint, measurement, true",
                  [*p("torque_setpoint", "joint_torque"), truth_path("spring_torque_nm")]),
            plot("torque loop effort [1]: controller output, duty",
                  p("torque_controller_output", "motor_duty_command")),
        ),
        rrb.Horizontal(
            plot("motor velocity [rad/s]: measured vs true",
                  [*p("motor_velocity"), truth_path("motor_velocity_rad_s")]),
            plot("spring constant [N*m/rad]: estimate vs true",
                  [*p("spring_constant_estimate"), truth_path(TRUE_SPRING_STIFFNESS)]),
            plot("spring constant estimate: confidence [1]", p("spring_constant_confidence")),
        ),
        plot("duty [1]: sent by the node, derate, applied by the plant",
              [*p("motor_duty_command", "thermal_derate"), truth_path("applied_duty")]),
    ))


def thermal(table: EntryTable) -> rrb.Blueprint:
    """Winding temperature (measured vs true), derating, resistance and current."""
    p = Paths(table)
    return blueprint_of(rrb.Vertical(
        plot("winding temperature [degC]: measured vs true, warning and limit",
              [*p("winding_temperature", "thermal_warning_c", "thermal_limit_c"),
               truth_path("winding_temperature_c")]),
        rrb.Horizontal(
            plot("thermal derate and duty [1]", p("thermal_derate", "motor_duty_command")),
            # Apart: the NTC's kilo-ohms would flatten the winding's ohm on one axis.
            plot("thermistor resistance [ohm] (what the firmware reads the temperature from)",
                  p("thermistor_resistance")),
            plot("winding resistance [ohm], true (rises with its temperature)",
                  [truth_path("winding_resistance_ohm")]),
        ),
        plot("motor current [A]: measured vs true", [*p("motor_current"), truth_path("current_a")]),
        events("Events"),
    ))


def faults(table: EntryTable) -> rrb.Blueprint:
    """Fault flags, safe state, watchdog and LED next to the NMT/EMCY/SDO event log."""
    p = Paths(table)
    return blueprint_of(rrb.Horizontal(
        rrb.Vertical(
            plot("fault flags and fault clear", p("fault_flags", "fault_clear")),
            plot("safe state, watchdog, LED", p("safe_state", "watchdog_tripped", "led_pattern")),
            plot("control mode", p("control_mode")),
        ),
        events(),
        column_shares=[3, 2],
    ), timeline=CYCLE_TIMELINE)


def timed_bus_views() -> list[rrb.View]:
    """A run on the timed bus (`hilrig.engine.bustiming`): its real load per cycle (at most 100 %)
    and the frames it made wait; empty on the ideal bus."""
    return [
        plot("timed bus load per cycle [% of its bit rate, at most 100]", [TIMED_LOAD_PATH]),
        plot("timed bus: frames waiting, frames delivered late", [TIMED_BACKLOG_PATH, TIMED_LATE_PATH]),
    ]


def bus(table: EntryTable) -> rrb.Blueprint:
    """What the bus carried, measured (`hilrig.observe.busmeter`): its load per 10 ms window in %
    of the bit rate, each TPDO's delay after its SYNC, the TPDOs late, missing or malformed and
    the error frames counted and as events (with which PDOs the node uses), SDO aborts, EMCY
    and NMT. The same from a live run and from `hilrig replay LOG --trace`."""
    return blueprint_of(rrb.Vertical(
        rrb.Horizontal(
            plot("bus load per 10 ms [% of the bit rate, worst-case bit stuffing]", [BUS_LOAD_PATH]),
            plot("each TPDO's delay after its SYNC [ms]", origin=BUS_DELAY_ROOT),
            *timed_bus_views(),
        ),
        rrb.Horizontal(
            plot("late, missing, malformed TPDOs and error frames [count so far]",
                  [problem_path(problem) for problem in BusProblem]),
            rrb.TextLogView(name="PDOs in use; late, missing, malformed TPDOs; error frames",
                            origin=BUS_EVENTS_PATH),
            rrb.TextLogView(name="SDO aborts", origin=SDO_PATH),
            rrb.TextLogView(name="EMCY and NMT",
                            origin="/", contents=[f"+ {EMCY_PATH}/**", f"+ {NMT_PATH}/**"]),
        ),
        row_shares=[3, 2],
    ), timeline=CYCLE_TIMELINE)


def named_fields(table: EntryTable) -> list[str]:
    """Every board field some dashboard plots by name, in first-named order: what a trace must
    hold for no plot to miss a series (`hilrig sim` polls the ones no PDO carries)."""
    field_of = {path: name for name, path in entity_paths(table).items()}
    names: dict[str, None] = {}

    def walk(part: rrb.Container | rrb.View) -> None:
        if isinstance(part, rrb.View):
            contents = part.contents if isinstance(part.contents, list) else []
            names.update((field_of[c], None) for c in contents if isinstance(c, str) and c in field_of)
        else:
            for child in part.contents:
                walk(child)

    for build in BLUEPRINTS.values():
        root = build(table).root_container
        if root is not None:
            walk(root)
    return list(names)


BLUEPRINTS: dict[str, Callable[[EntryTable], rrb.Blueprint]] = {
    "overview": overview,
    "tuning": tuning,
    "thermal": thermal,
    "faults": faults,
    "bus": bus,
    "robot": robot,
    "diff": diff,
}
"""The joint's blueprint builders by name (with a robot's and a comparison's); every board's are
the package's `dashboards.BLUEPRINTS`, and `dashboards.blueprint(name, table)` the way to get one."""
