"""The dashboard of any board, generated from its table and its plant's truth: what a trace of a
board without hand-made dashboards opens with (`hilrig view`, and the blueprint in its .rrd).

    board(table, truth=plant.truth_fields)              # before a run: what the PDOs carry
    board(table, present=entities_with_data(trace))     # for a trace: and whatever else it holds

One plot per unit (the table's units, the truth's from its names' suffixes): the commands and
parameters of that unit beside the firmware's fields of it (sensors, derived, modules,
actuators) and the plant's truth, so a command sits beside the measurements it drives and the
truth beside the firmware's belief. Then the raw HIL I/O per unit, the fields with named values
(modes, fault flags) with their names as they change, the event log (NMT, EMCY, SDO, bus,
injected faults) and the bus (load, each TPDO's delay, problems, frames per cycle).

Which fields: before a run, every one a PDO of the table carries. For a trace (`present` given),
every one a TPDO carries (what the node sends every cycle it is due) and every other one the
trace holds (a command the rig sent, a parameter written over SDO, a field polled): a command
the scenario never sent is not expected. So a trace has every series drawn, and a TPDO's field
the run never got is a gap `hilrig view --check` says.
Paths come from `hilrig.observe.paths`, like every dashboard's.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence

import rerun.blueprint as rrb

from boardproto import Field, Kind
from dashboards.joint import blueprint_of, events, plot
from hilrig.observe.paths import (
    BUS_DELAY_ROOT,
    BUS_FRAMES_ROOT,
    BUS_LOAD_PATH,
    BUS_ROOT,
    TIMED_BACKLOG_PATH,
    TIMED_LATE_PATH,
    TIMED_LOAD_PATH,
    TRUTH_ROOT,
    BusProblem,
    EntryTable,
    entity_paths,
    label_path,
    plant_truth_path,
    problem_path,
    truth_unit,
)

MAX_SERIES_PER_PLOT = 8
"""More series of one unit than this are split over several plots, each still readable."""

ROLES: tuple[tuple[str, tuple[Kind, ...]], ...] = (
    ("commanded", (Kind.COMMAND,)),
    ("parameters", (Kind.PARAMETER,)),
    ("firmware", (Kind.SENSOR, Kind.VIRTUAL_SENSOR, Kind.MODULE)),
    ("driven", (Kind.ACTUATOR,)),
)
"""How a unit's plot groups the board's fields, in this order, then the truth ("true")."""

PER_CYCLE_ROOT = f"{BUS_ROOT}/per_cycle"


def pdo_carried(table: EntryTable, *, tpdos_only: bool = False) -> set[str]:
    """The names of every field and HIL I/O object an enabled PDO (or TPDO) of the table maps."""
    pdos = table.board.tpdos if tpdos_only else table.board.pdos
    return {entry.name for pdo in pdos if pdo.enabled for entry in pdo.entries}


def truth_of(present: Iterable[str]) -> list[str]:
    """The truth quantities among entity paths (/truth/<quantity>), in order."""
    prefix = TRUTH_ROOT + "/"
    quantities = (path.removeprefix(prefix) for path in present if path.startswith(prefix))
    return [quantity for quantity in quantities if "/" not in quantity]


def _chunks(title: str, paths: Sequence[str]) -> Iterator[rrb.TimeSeriesView]:
    """`paths` on one plot, or on several of at most MAX_SERIES_PER_PLOT each."""
    parts = [paths[k : k + MAX_SERIES_PER_PLOT] for k in range(0, len(paths), MAX_SERIES_PER_PLOT)]
    for k, part in enumerate(parts):
        yield plot(title if len(parts) == 1 else f"{title} ({k + 1}/{len(parts)})", list(part))


def _titled(unit: str, groups: Sequence[tuple[str, Sequence[str]]]) -> str:
    said = "; ".join(f"{role} {', '.join(names)}" for role, names in groups if names)
    return f"[{unit}] {said}"


def board(
    table: EntryTable, truth: Iterable[str] = (), present: Iterable[str] | None = None
) -> rrb.Blueprint:
    """The generated dashboard of `table`'s board (see the module docstring). truth: the plant's
    truth quantities (`Plant.truth_fields` and its `truth_parameters`' names); present: entity
    paths a trace has data at (its truth among them), None before a run."""
    carried = pdo_carried(table, tpdos_only=present is not None)
    present = list(present or ())
    with_data = set(present)
    paths = entity_paths(table)
    shown = [e for e in table.board.entries if e.name in carried or paths[e.name] in with_data]
    named = [e for e in shown if e.name in table.board.named_values]
    quantities = list(dict.fromkeys([*truth, *truth_of(present)]))

    signals: list[rrb.TimeSeriesView] = []
    fields = [e for e in shown if isinstance(e, Field) and e not in named]
    units = list(dict.fromkeys([*(f.unit for f in fields), *(truth_unit(q) for q in quantities)]))
    for unit in units:
        groups = [
            (role, [f.name for f in fields if f.unit == unit and f.kind in kinds]) for role, kinds in ROLES
        ]
        true = [q for q in quantities if truth_unit(q) == unit]
        series = [paths[name] for _, names in groups for name in names] + [plant_truth_path(q) for q in true]
        signals += _chunks(_titled(unit, [*groups, ("true", true)]), series)

    raw = [e for e in shown if not isinstance(e, Field) and e not in named]
    for unit in dict.fromkeys(e.unit for e in raw):
        groups = [
            (f"HIL {direction}", [e.name for e in raw if e.unit == unit and e.direction.value == direction])
            for direction in ("input", "output")
        ]
        signals += _chunks(_titled(unit, groups), [paths[name] for _, names in groups for name in names])

    states: list[rrb.View] = []
    for unit in dict.fromkeys(e.unit for e in named):
        names = [e.name for e in named if e.unit == unit]
        states += _chunks(f"[{unit}] named values: {', '.join(names)}", [paths[name] for name in names])
    if named:
        states.append(
            rrb.TextLogView(
                name="named values as they change",
                origin="/",
                contents=[f"+ {label_path(paths[e.name])}" for e in named],
            )
        )
    return blueprint_of(
        rrb.Vertical(
            rrb.Grid(*signals),
            rrb.Horizontal(*states, events(), column_shares=[*(1 for _ in states), 2]),
            rrb.Horizontal(*bus_views()),
            row_shares=[4, 2, 2],
        )
    )


def bus_views() -> list[rrb.View]:
    """What the bus carried: its load, each TPDO's delay, the problems counted, frames per cycle."""
    return [
        plot("bus load per 10 ms [% of the bit rate]", [BUS_LOAD_PATH]),
        plot("timed bus load per cycle [% of its bit rate, at most 100]", [TIMED_LOAD_PATH]),
        plot("timed bus: frames waiting, frames delivered late", [TIMED_BACKLOG_PATH, TIMED_LATE_PATH]),
        plot("each TPDO's delay after its SYNC [ms]", origin=BUS_DELAY_ROOT),
        plot(
            "late, missing, malformed TPDOs and error frames [count so far]",
            [problem_path(problem) for problem in BusProblem],
        ),
        plot(
            "frames per cycle: per PDO, per direction",
            [f"+ {BUS_FRAMES_ROOT}/**", f"+ {PER_CYCLE_ROOT}/**"],
        ),
    ]
