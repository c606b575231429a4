"""The plant map: how an FMU's variables meet a board's HIL I/O, read from a small TOML file next
to the table and checked at load against the FMU's modelDescription.xml and the board's table.

    fmu = "oscillator.fmu"          # optional: the FMU, relative to this file (--plant wins)
    substeps = 1                    # doStep calls per control period (an integer >= 1)

    [parameters]                    # FMU parameters set before initialisation (SI, as declared)
    "c[4]" = 4.0

    [[input]]                       # FMU input  <- a HIL output (the node's actuator, wire value)
    variable = "f[4]"               # value = wire * scale + offset
    unit = "N.m"                    # the variable's unit in modelDescription.xml, checked
    field = "rail_switch"
    scale = 0.5

    [[output]]                      # FMU output -> a HIL input (the node's sensor, wire value)
    variable = "v[4]"               # wire = round(value * scale + offset + noise), in range
    unit = "rad/s"
    field = "gyro_y_counts"
    scale = 1000.0
    noise = 2.0                     # optional: standard deviation of seeded noise [wire units]
    truth = "pitch_rate_rad_s"      # optional: its name in the trace's truth

    [[constant]]                    # a HIL input the FMU does not model, held at a wire value
    field = "battery_adc"
    value = 12000

    [[truth]]                       # more of the FMU's variables in the trace's truth
    variable = "x[4]"
    unit = "rad"
    name = "pitch_rad"

Every mistake is a one-line `PlantMapError` naming the map, the entry and what to do: a variable
the FMU does not have, a wrong causality (an [[input]] that is not an FMU input...), a unit that
is not the declared one, a field that is not a HIL input/output of the table, a HIL input with no
source. `field_unit`, optional in [[input]]/[[output]], is checked against the table's unit.
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from boardproto import BoardTable
from hilrig.errors import PlantMapError

OUTPUT_CAUSALITIES = ("output",)
"""What an [[output]] may read: the FMU's outputs."""
TRUTH_CAUSALITIES = ("output", "local", "parameter", "calculatedParameter")
"""What a [[truth]] entry may read: any variable whose value the FMU exposes."""
PARAMETER_CAUSALITIES = ("parameter",)
"""What [parameters] may set before initialisation."""
_ENTRY_KEYS = {
    "input": {"variable", "unit", "field", "scale", "offset", "field_unit"},
    "output": {"variable", "unit", "field", "scale", "offset", "field_unit", "noise", "truth"},
    "constant": {"field", "value"},
    "truth": {"variable", "unit", "name"},
}
_TOP_KEYS = {"fmu", "substeps", "parameters", *_ENTRY_KEYS}


@dataclass(frozen=True)
class Link:
    """One FMU variable tied to one HIL I/O object: `value = wire * scale + offset` (inputs),
    `wire = round(value * scale + offset + noise)` clamped to the object's range (outputs)."""

    variable: str
    value_reference: int
    field: str
    scale: float
    offset: float
    low: int
    high: int
    noise: float = 0.0
    truth: str | None = None


@dataclass(frozen=True)
class TruthVariable:
    """An FMU variable shown in the trace's truth under `name` (SI, unit in the name)."""

    name: str
    variable: str
    value_reference: int


@dataclass(frozen=True)
class PlantMap:
    """A checked map (see the module docstring): what `hilrig.plants.fmu.FmuPlant` runs."""

    path: Path
    fmu: Path
    fmi_version: str
    guid: str
    model_identifier: str
    can_save_state: bool
    substeps: int
    parameters: Mapping[str, tuple[int, str, float]]
    """name -> (value reference, FMI type, value): the map's [parameters]."""
    settable: Mapping[str, tuple[int, str]]
    """Every parameter of the FMU, name -> (value reference, FMI type): what a scenario's params
    may set."""
    inputs: tuple[Link, ...]
    outputs: tuple[Link, ...]
    constants: Mapping[str, int]
    truth: tuple[TruthVariable, ...]

    @property
    def sensor_fields(self) -> tuple[str, ...]:
        return (*(link.field for link in self.outputs), *self.constants)

    @property
    def actuator_fields(self) -> tuple[str, ...]:
        return tuple(link.field for link in self.inputs)


def truth_name(variable: str, unit: str) -> str:
    """A variable's default truth name: its name as an identifier, the unit as suffix (`v[4]`,
    rad/s -> `v_4_rad_s`)."""
    words = [part for part in re.split(r"\W+", f"{variable} {unit}") if part]
    return "_".join(words)


def _fail(where: str, problem: str) -> PlantMapError:
    return PlantMapError(f"{where}: {problem}")


def _number(entry: Mapping[str, Any], key: str, where: str, default: float) -> float:
    value = entry.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise _fail(where, f"{key} must be a number, not {value!r}")
    return float(value)


def _text(entry: Mapping[str, Any], key: str, where: str) -> str:
    value = entry.get(key)
    if not isinstance(value, str):
        raise _fail(where, f'needs {key} = "..." (a string)')
    return value


def _declared_unit(variable: Any) -> str:
    if variable.unit:
        return str(variable.unit)
    declared = getattr(variable, "declaredType", None)
    return str(declared.unit) if declared is not None and getattr(declared, "unit", None) else ""


def load_map(path: str | Path, table: BoardTable, fmu: str | Path | None = None) -> PlantMap:
    """Read and check the map at `path` for the board of `table`, with the FMU `fmu` (None: the
    map's own `fmu`, relative to the map). Raises PlantMapError (one line) on any mistake."""
    from fmpy import read_model_description

    map_path = Path(path)
    try:
        raw = tomllib.loads(map_path.read_text(encoding="utf-8"))
    except OSError as error:
        raise PlantMapError(f"plant map {map_path}: {error.strerror or error}") from None
    except tomllib.TOMLDecodeError as error:
        raise PlantMapError(f"plant map {map_path}: not TOML: {error}") from None
    unknown = sorted(set(raw) - _TOP_KEYS)
    if unknown:
        raise _fail(f"plant map {map_path}", f"unknown key(s) {unknown}: expected {sorted(_TOP_KEYS)}")
    if fmu is None:
        if "fmu" not in raw:
            raise _fail(f"plant map {map_path}", 'names no fmu: add fmu = "model.fmu" or give --plant')
        fmu = map_path.parent / _text(raw, "fmu", f"plant map {map_path}")
    fmu_path = Path(fmu)
    if not fmu_path.is_file():
        raise PlantMapError(f"FMU {fmu_path}: no such file")
    try:
        description = read_model_description(str(fmu_path), validate=False)
    except Exception as error:  # fmpy raises plain Exceptions for a file that is not an FMU
        raise PlantMapError(f"FMU {fmu_path}: cannot read its modelDescription.xml ({error})") from None
    if description.coSimulation is None:
        raise PlantMapError(
            f"FMU {fmu_path}: not a co-simulation FMU (model exchange only): export it for co-simulation"
        )
    variables = {variable.name: variable for variable in description.modelVariables}
    hil_inputs = {io.name: io for io in table.hil_inputs}
    hil_outputs = {io.name: io for io in table.hil_outputs}
    where_map = f"plant map {map_path.name}"

    def variable_of(entry: Mapping[str, Any], where: str, causalities: tuple[str, ...]) -> Any:
        name = _text(entry, "variable", where)
        variable = variables.get(name)
        if variable is None:
            raise _fail(where, f"the FMU {fmu_path.name} has no variable {name!r}")
        if variable.causality not in causalities:
            raise _fail(where, f"{name} is an FMU {variable.causality}, expected {' or '.join(causalities)}")
        if variable.type not in ("Real", "Float64", "Float32"):
            raise _fail(where, f"{name} is of type {variable.type}: only real variables map to fields")
        unit, declared = _text(entry, "unit", where), _declared_unit(variable)
        if unit != declared:
            raise _fail(where, f"{name} is in {declared or 'no unit'} in the FMU, the map says {unit!r}")
        return variable

    def link_of(kind: str, index: int, entry: Mapping[str, Any], ios: Mapping[str, Any]) -> Link:
        where = f"{where_map} [[{kind}]] #{index + 1}"
        unknown_keys = sorted(set(entry) - _ENTRY_KEYS[kind])
        if unknown_keys:
            raise _fail(where, f"unknown key(s) {unknown_keys}: expected {sorted(_ENTRY_KEYS[kind])}")
        variable = variable_of(entry, where, ("input",) if kind == "input" else OUTPUT_CAUSALITIES)
        field = _text(entry, "field", where)
        io = ios.get(field)
        if io is None:
            other = "output" if kind == "input" else "input"
            raise _fail(where, f"{field!r} is not a HIL {other} of the table: one of {sorted(ios)}")
        if "field_unit" in entry and entry["field_unit"] != io.unit:
            raise _fail(where, f"{field} is in {io.unit} in the table, the map says {entry['field_unit']!r}")
        truth = entry.get("truth")
        if truth is not None and not isinstance(truth, str):
            raise _fail(where, "truth must be a name (a string)")
        return Link(
            variable=variable.name,
            value_reference=int(variable.valueReference),
            field=field,
            scale=_number(entry, "scale", where, 1.0),
            offset=_number(entry, "offset", where, 0.0),
            low=int(io.min),
            high=int(io.max),
            noise=_number(entry, "noise", where, 0.0),
            truth=truth if truth is not None else truth_name(variable.name, _declared_unit(variable)),
        )

    def entries(kind: str) -> list[Mapping[str, Any]]:
        found = raw.get(kind, [])
        if not isinstance(found, list) or not all(isinstance(entry, dict) for entry in found):
            raise _fail(where_map, f"{kind} must be an array of tables: [[{kind}]]")
        return found

    inputs = tuple(link_of("input", i, e, hil_outputs) for i, e in enumerate(entries("input")))
    outputs = tuple(link_of("output", i, e, hil_inputs) for i, e in enumerate(entries("output")))
    constants: dict[str, int] = {}
    for index, entry in enumerate(entries("constant")):
        where = f"{where_map} [[constant]] #{index + 1}"
        field = _text(entry, "field", where)
        io = hil_inputs.get(field)
        if io is None:
            raise _fail(where, f"{field!r} is not a HIL input of the table: one of {sorted(hil_inputs)}")
        value = entry.get("value")
        if isinstance(value, bool) or not isinstance(value, int) or not io.min <= value <= io.max:
            raise _fail(where, f"value must be a wire value of {field}, an integer in {io.min}..{io.max}")
        constants[field] = value
    truth = [TruthVariable(link.truth, link.variable, link.value_reference) for link in outputs if link.truth]
    for index, entry in enumerate(entries("truth")):
        where = f"{where_map} [[truth]] #{index + 1}"
        variable = variable_of(entry, where, TRUTH_CAUSALITIES)
        name = entry.get("name", truth_name(variable.name, _declared_unit(variable)))
        truth.append(TruthVariable(str(name), variable.name, int(variable.valueReference)))
    sources = [link.field for link in outputs] + list(constants)
    twice = sorted({name for name in sources if sources.count(name) > 1})
    if twice:
        raise _fail(where_map, f"HIL input(s) {twice} have more than one source: keep one")
    missing = [name for name in hil_inputs if name not in sources]
    if missing:
        raise _fail(where_map, f"HIL input(s) {missing} have no source: add an [[output]] or a [[constant]]")
    driven = [link.field for link in inputs]
    if len(set(driven)) != len(driven):
        raise _fail(where_map, "a HIL output drives more than one FMU input: map each once")
    names = [entry.name for entry in truth]
    if len(set(names)) != len(names):
        raise _fail(where_map, f"truth names repeat ({names}): give each a name of its own")
    parameters: dict[str, tuple[int, str, float]] = {}
    spelled = raw.get("parameters", {})
    if not isinstance(spelled, dict):
        raise _fail(where_map, "parameters must be a table: [parameters]")
    for name, value in spelled.items():
        parameters[name] = parameter_of(variables, name, value, f"{where_map} [parameters]")
    substeps = raw.get("substeps", 1)
    if isinstance(substeps, bool) or not isinstance(substeps, int) or substeps < 1:
        raise _fail(where_map, f"substeps must be an integer >= 1, not {substeps!r}")
    cosim = description.coSimulation
    return PlantMap(
        path=map_path,
        fmu=fmu_path,
        fmi_version=str(description.fmiVersion),
        guid=str(description.guid or description.instantiationToken or ""),
        model_identifier=str(cosim.modelIdentifier),
        can_save_state=bool(cosim.canGetAndSetFMUstate),
        substeps=substeps,
        parameters=parameters,
        settable={
            name: (int(variable.valueReference), str(variable.type))
            for name, variable in variables.items()
            if variable.causality in PARAMETER_CAUSALITIES
        },
        inputs=inputs,
        outputs=outputs,
        constants=constants,
        truth=tuple(truth),
    )


def parameter_of(
    variables: Mapping[str, Any], name: str, value: object, where: str
) -> tuple[int, str, float]:
    """A parameter the map (or a scenario's params) sets: (value reference, type, value)."""
    variable = variables.get(name)
    if variable is None:
        raise _fail(where, f"the FMU has no variable {name!r}")
    if variable.causality not in PARAMETER_CAUSALITIES:
        raise _fail(where, f"{name} is an FMU {variable.causality}, not a parameter")
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise _fail(where, f"{name} must be a number, not {value!r}")
    return int(variable.valueReference), str(variable.type), float(value)


__all__ = ["Link", "PlantMap", "TruthVariable", "load_map", "parameter_of", "truth_name"]
