"""Rerun blueprints for the demo joint, built from the entity paths the tracer logs.

    python -m dashboards overview out/scenarios/<test>/trace.rrd       # open a trace with a view
    blueprint("tuning")                                                # rerun.blueprint.Blueprint

Every path comes from `hilrig.trace` and every field name is checked against board.toml when
a blueprint is built, so a renamed field fails here with close matches instead of showing an
empty plot.
"""

from __future__ import annotations

from collections.abc import Callable

import rerun.blueprint as rrb

from boardproto import Kind
from dashboards.robot import robot
from hilrig.table import RigTable, unknown_name
from hilrig.trace import (
    CYCLE_TIMELINE,
    EVENTS_ROOT,
    HIL_INPUTS_ROOT,
    HIL_OUTPUTS_ROOT,
    SIM_TIME_TIMELINE,
    TRUE_SPRING_STIFFNESS,
    entity_paths,
    kind_path,
    truth_path,
)


class _Paths:
    """Field name -> entity path, checked against the table."""

    def __init__(self, table: RigTable) -> None:
        self._table = table
        self._paths = entity_paths(table)

    def __call__(self, *names: str) -> list[str]:
        self._table.check(names)
        return [self._paths[name] for name in names]


def _plot(name: str, contents: list[str]) -> rrb.TimeSeriesView:
    return rrb.TimeSeriesView(name=name, origin="/", contents=contents)


def _events(name: str = "Events (NMT, EMCY, SDO aborts)") -> rrb.TextLogView:
    return rrb.TextLogView(name=name, origin=EVENTS_ROOT)


def _blueprint(*parts: rrb.Container | rrb.View, timeline: str = SIM_TIME_TIMELINE) -> rrb.Blueprint:
    return rrb.Blueprint(*parts, rrb.TimePanel(timeline=timeline), collapse_panels=False)


def overview(table: RigTable) -> rrb.Blueprint:
    """Every group of fields in its own plot, truth beside them, the event log below."""
    kinds = [rrb.TimeSeriesView(name=kind.value.replace("_", " ") + "s", origin=kind_path(kind))
             for kind in (Kind.SENSOR, Kind.VIRTUAL_SENSOR, Kind.MODULE, Kind.COMMAND, Kind.PARAMETER)]
    return _blueprint(rrb.Vertical(
        rrb.Grid(
            *kinds,
            rrb.TimeSeriesView(name="HIL inputs (raw, sent)", origin=HIL_INPUTS_ROOT),
            rrb.TimeSeriesView(name="HIL outputs (raw, received)", origin=HIL_OUTPUTS_ROOT),
            rrb.TimeSeriesView(name="ground truth", origin="/truth"),
        ),
        _events(),
        row_shares=[4, 1],
    ))


def tuning(table: RigTable) -> rrb.Blueprint:
    """Controller tuning: setpoint, measurement (and its truth) and command on one plot per loop."""
    p = _Paths(table)
    return _blueprint(rrb.Vertical(
        _plot("velocity loop: setpoint, measurement, truth, command",
              [*p("velocity_setpoint", "output_velocity", "velocity_controller_output", "motor_duty_command"),
               truth_path("load_velocity_rad_s")]),
        _plot("torque loop: setpoint, measurement, truth, command",
              [*p("torque_setpoint", "joint_torque", "torque_controller_output", "motor_duty_command"),
               truth_path("spring_torque_nm")]),
        rrb.Horizontal(
            _plot("motor velocity: measured vs true",
                  [*p("motor_velocity"), truth_path("motor_velocity_rad_s")]),
            _plot("spring constant: estimate vs true",
                  [*p("spring_constant_estimate", "spring_constant_confidence"),
                   truth_path(TRUE_SPRING_STIFFNESS)]),
        ),
        _plot("duty: applied by the plant vs sent by the node",
              [*p("motor_duty_command", "thermal_derate"), truth_path("applied_duty")]),
    ))


def thermal(table: RigTable) -> rrb.Blueprint:
    """Winding temperature (measured vs true), derating, resistance and current."""
    p = _Paths(table)
    return _blueprint(rrb.Vertical(
        _plot("winding temperature: measured vs true",
              [*p("winding_temperature", "thermal_warning_c", "thermal_limit_c"),
               truth_path("winding_temperature_c")]),
        rrb.Horizontal(
            _plot("thermal derate", p("thermal_derate", "motor_duty_command")),
            _plot("thermistor / winding resistance",
                  [*p("thermistor_resistance"), truth_path("winding_resistance_ohm")]),
        ),
        _plot("motor current: measured vs true", [*p("motor_current"), truth_path("current_a")]),
        _events("Events"),
    ))


def faults(table: RigTable) -> rrb.Blueprint:
    """Fault flags, safe state, watchdog and LED next to the NMT/EMCY/SDO event log."""
    p = _Paths(table)
    return _blueprint(rrb.Horizontal(
        rrb.Vertical(
            _plot("fault flags", p("fault_flags", "fault_clear")),
            _plot("safe state, watchdog, LED", p("safe_state", "watchdog_tripped", "led_pattern")),
            _plot("commands", p("control_mode", "velocity_setpoint", "torque_setpoint")),
        ),
        _events(),
        column_shares=[3, 2],
    ), timeline=CYCLE_TIMELINE)


def named_fields(table: RigTable) -> list[str]:
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


BLUEPRINTS: dict[str, Callable[[RigTable], rrb.Blueprint]] = {
    "overview": overview,
    "tuning": tuning,
    "thermal": thermal,
    "faults": faults,
    "robot": robot,
}
"""Blueprint builders by name; `blueprint(name)` is the way to get one."""


def blueprint(name: str, table: RigTable | None = None) -> rrb.Blueprint:
    """The blueprint called `name` (FieldNameError listing close matches for a typo)."""
    try:
        build = BLUEPRINTS[name]
    except KeyError:
        raise unknown_name("dashboard", name, BLUEPRINTS) from None
    return build(table if table is not None else RigTable.load())
