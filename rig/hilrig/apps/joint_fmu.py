"""The demo joint's plant as an FMI 2.0 co-simulation FMU, built by `make build`:
build/fmu/joint.fmu, checked by FMPy's own validation, and build/fmu/joint.map.toml, the plant
map that puts it on the demo board with the demo's parameters (`hilrig sim --plant`).

    .venv/bin/python tools/joint_fmu.py [--out build/fmu]      (this app's `main`)

The C is rig/hilrig/plants/_joint_fmu.c on _joint_core.h, the arithmetic the rig's own joint
runs (_plant.c). This module is the home of the FMU's variables: their names come from the rig
(plant.plant_coefficients, sensors.sensor_coefficients, the RawSensors fields, JointState's),
their units from the board's table; it writes the value references and start values the C
reads (joint_fmu_variables.h) and modelDescription.xml, compiles against the FMI 2.0 headers
FMPy ships, and zips. Rebuilt only when an input changed (the FMU's own files and this module).
"""

from __future__ import annotations

import argparse
import hashlib
import os
import subprocess
import sys
import tempfile
import uuid
import zipfile
from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import quoteattr

from hilrig.resources import JOINT_FMU, JOINT_FMU_DIR, JOINT_FMU_MAP

PLANTS = Path(__file__).resolve().parents[1] / "plants"
SOURCES = (PLANTS / "_joint_fmu.c", PLANTS / "_joint_core.h", Path(__file__).resolve())
MODEL_IDENTIFIER = "hilrig_joint"

DEFAULT_OUT = JOINT_FMU_DIR
FMU_NAME = JOINT_FMU.name
MAP_NAME = JOINT_FMU_MAP.name
CFLAGS = ("-std=c99", "-O2", "-ffp-contract=off", "-fno-fast-math", "-Wall", "-Wextra", "-Werror", "-fPIC")
"""_plant.c's floating-point flags (setup.py): the same bits as the rig's joint."""
DESCRIPTION = (
    "hil-rig's demo joint: DC motor, gearbox, series-elastic spring, load, winding heat, encoders, "
    "NTC thermistor, current sensor"
)
STEP_S = 0.001
"""The default experiment's communication step: the demo's control period."""


@dataclass(frozen=True)
class Variable:
    name: str
    causality: str
    start: float | None = None
    unit: str = ""
    description: str = ""


def _unit_of(name: str) -> str:
    """SI unit of a JointState quantity, from its name's suffix."""
    for suffix, unit in (("_rad_s", "rad/s"), ("_rad", "rad"), ("_a", "A"), ("_c", "degC"), ("_nm", "N.m")):
        if name.endswith(suffix):
            return unit
    return {"winding_resistance_ohm": "Ohm", "applied_duty": "1"}[name]


def variables() -> tuple[list[Variable], dict[str, int]]:
    """Every variable in value-reference order, and the C's layout (macro -> value)."""
    from hilrig.plants.joint import ACTUATOR_FIELD
    from hilrig.plants.params import JointParams
    from hilrig.plants.plant import MOTOR_DUTY_FULL_SCALE, STATE_FIELDS, joint_coefficients
    from hilrig.plants.sensors import NOISE_COEFFICIENTS, RawSensors, sensor_coefficients
    from hilrig.table import BOARD_TABLE

    defaults = JointParams()
    plant = joint_coefficients(defaults)
    sensors = {k: v for k, v in sensor_coefficients(defaults).items() if k not in NOISE_COEFFICIENTS}
    assert list(sensor_coefficients(defaults))[len(sensors) :] == list(NOISE_COEFFICIENTS)
    units = {io.name: io.unit for io in (*BOARD_TABLE.hil_inputs, *BOARD_TABLE.hil_outputs)}
    found = [Variable(name, "parameter", value) for name, value in plant.items()]
    found += [Variable(name, "parameter", value) for name, value in sensors.items()]
    found.append(Variable("ambient_temperature_c", "parameter", defaults.ambient_temperature_c, "degC"))
    parameter_count = len(found)
    found.append(
        Variable(
            ACTUATOR_FIELD,
            "input",
            0.0,
            units[ACTUATOR_FIELD],
            f"wire counts, {MOTOR_DUTY_FULL_SCALE} = full duty",
        )
    )
    readings = list(RawSensors.__dataclass_fields__)
    found += [
        Variable(name, "output", unit=units[name], description="as the rig sends it") for name in readings
    ]
    state = list(STATE_FIELDS[1:])
    found += [Variable(name, "output", unit=_unit_of(name)) for name in state]
    layout = {
        "VR_PLANT": 0,
        "VR_SENSOR": len(plant),
        "VR_SENSOR_PARAMETERS": len(sensors),
        "VR_AMBIENT": parameter_count - 1,
        "VR_PARAMETER_COUNT": parameter_count,
        "VR_MOTOR_DUTY": parameter_count,
        "VR_STATE": parameter_count + 1 + len(readings),
        "VR_COUNT": len(found),
        "JOINT_MOTOR_DUTY_FULL_SCALE": MOTOR_DUTY_FULL_SCALE,
    }
    for offset, name in enumerate(readings):
        layout[f"VR_{name.upper()}"] = parameter_count + 1 + offset
    for offset, name in enumerate(state):
        layout[f"VR_{name.upper()}"] = layout["VR_STATE"] + offset
    return found, layout


def model_description(found: list[Variable], guid: str) -> str:
    units = sorted({v.unit for v in found if v.unit})
    rows = []
    for reference, v in enumerate(found):
        attributes = f'name={quoteattr(v.name)} valueReference="{reference}" causality="{v.causality}"'
        if v.causality == "parameter":
            attributes += ' variability="fixed" initial="exact"'
        elif v.causality == "output":
            attributes += ' variability="continuous" initial="calculated"'
        else:
            attributes += ' variability="continuous"'
        if v.description:
            attributes += f" description={quoteattr(v.description)}"
        real = f' unit="{v.unit}"' if v.unit else ""
        if v.start is not None:
            real += f' start="{v.start!r}"'
        rows.append(f"    <ScalarVariable {attributes}>\n      <Real{real}/>\n    </ScalarVariable>")
    outputs = [index + 1 for index, v in enumerate(found) if v.causality == "output"]
    unknowns = "\n".join(f'      <Unknown index="{index}"/>' for index in outputs)
    unit_rows = "\n".join(f"    <Unit name={quoteattr(unit)}/>" for unit in units)
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="hilrig_joint" guid="{guid}"
  description="{DESCRIPTION}"
  generationTool="hil-rig tools/joint_fmu.py" variableNamingConvention="flat" numberOfEventIndicators="0">
  <CoSimulation modelIdentifier="{MODEL_IDENTIFIER}" canHandleVariableCommunicationStepSize="true"
    canGetAndSetFMUstate="true" canSerializeFMUstate="true" canNotUseMemoryManagementFunctions="true"/>
  <UnitDefinitions>
{unit_rows}
  </UnitDefinitions>
  <DefaultExperiment startTime="0.0" stepSize="{STEP_S!r}"/>
  <ModelVariables>
{chr(10).join(rows)}
  </ModelVariables>
  <ModelStructure>
    <Outputs>
{unknowns}
    </Outputs>
    <InitialUnknowns>
{unknowns}
    </InitialUnknowns>
  </ModelStructure>
</fmiModelDescription>
"""


def variables_header(found: list[Variable], layout: dict[str, int], guid: str) -> str:
    defines = "\n".join(f"#define {name} {value}" for name, value in layout.items())
    starts = "\n".join(f"    {v.start!r}, /* {v.name} */" for v in found[: layout["VR_PARAMETER_COUNT"]])
    return (
        "/* Generated by tools/joint_fmu.py: the joint FMU's value references and the parameters' start\n"
        " * values (JointParams' defaults). */\n"
        f'#define JOINT_FMU_GUID "{guid}"\n{defines}\n'
        f"static const double joint_fmu_start[VR_PARAMETER_COUNT] = {{\n{starts}\n}};\n"
    )


def plant_map(found: list[Variable]) -> str:
    """The map of the demo board on the FMU, with the demo's parameters (apps.demo.demo_params)
    and no noise of its own (the FMU has none; the native plant's is numpy's stream)."""
    from hilrig.apps.demo import demo_params
    from hilrig.plants.joint import ACTUATOR_FIELD
    from hilrig.plants.plant import joint_coefficients
    from hilrig.plants.sensors import RawSensors, sensor_coefficients

    params = demo_params()
    values = joint_coefficients(params)
    values |= sensor_coefficients(params)
    values["ambient_temperature_c"] = params.ambient_temperature_c
    by_name = {v.name: v for v in found}
    lines = [
        "# Generated by tools/joint_fmu.py (`make build`): the demo board on the joint's own FMU, with",
        "# the demo's parameters:",
        "#   hilrig sim --plant build/fmu/joint.fmu --plant-map build/fmu/joint.map.toml",
        f'fmu = "{FMU_NAME}"',
        "substeps = 1",
        "",
        "[parameters]",
    ]
    lines += [f"{name} = {values[name]!r}" for name, v in by_name.items() if v.causality == "parameter"]
    unit = by_name[ACTUATOR_FIELD].unit
    lines += [
        "",
        "[[input]]",
        f'variable = "{ACTUATOR_FIELD}"',
        f'unit = "{unit}"',
        f'field = "{ACTUATOR_FIELD}"',
    ]
    for name in RawSensors.__dataclass_fields__:
        lines += [
            "",
            "[[output]]",
            f'variable = "{name}"',
            f'unit = "{by_name[name].unit}"',
            f'field = "{name}"',
        ]
    for v in found:
        if v.causality == "output" and v.name not in RawSensors.__dataclass_fields__:
            lines += ["", "[[truth]]", f'variable = "{v.name}"', f'unit = "{v.unit}"', f'name = "{v.name}"']
    return "\n".join(lines) + "\n"


def fmpy_headers() -> Path:
    import fmpy

    headers = Path(fmpy.__file__).resolve().parent / "c-code"
    if not (headers / "fmi2Functions.h").is_file():
        raise SystemExit(
            f"joint_fmu: FMPy at {headers.parent} has no FMI 2.0 headers: reinstall it (make deps)"
        )
    return headers


def build(out: Path) -> Path:
    """build/fmu/joint.fmu and its map; returns the FMU's path."""
    found, layout = variables()
    description = model_description(found, "{00000000-0000-0000-0000-000000000000}")
    digest = hashlib.sha256(description.encode())
    for source in SOURCES:
        digest.update(source.read_bytes())
    guid = "{" + str(uuid.UUID(digest.hexdigest()[:32])) + "}"
    description = model_description(found, guid)
    fmu = out / FMU_NAME
    out.mkdir(parents=True, exist_ok=True)
    (out / MAP_NAME).write_text(plant_map(found))
    if fmu.is_file():
        with zipfile.ZipFile(fmu) as existing:
            if existing.read("modelDescription.xml").decode() == description:
                return fmu  # the same GUID: the same sources and variables
    with tempfile.TemporaryDirectory(prefix="joint-fmu-") as scratch:
        work = Path(scratch)
        (work / "joint_fmu_variables.h").write_text(variables_header(found, layout, guid))
        library = work / f"{MODEL_IDENTIFIER}.so"
        compiler = os.environ.get("CC", "cc")
        command = [
            compiler, *CFLAGS, "-shared", f"-I{fmpy_headers()}", f"-I{PLANTS}", f"-I{work}",
            "-o", str(library), str(PLANTS / "_joint_fmu.c"), "-lm",
        ]  # fmt: skip
        try:
            subprocess.run(command, check=True)
        except (OSError, subprocess.CalledProcessError) as error:
            raise SystemExit(f"joint_fmu: compiling {PLANTS / '_joint_fmu.c'} failed ({error})") from None
        partial = fmu.with_suffix(".fmu.partial")
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as archive:
            archive.writestr("modelDescription.xml", description)
            archive.write(library, f"binaries/linux64/{MODEL_IDENTIFIER}.so")
        partial.replace(fmu)
    return fmu


def validate(fmu: Path) -> list[str]:
    """FMPy's own checks of the FMU (its modelDescription.xml against the FMI 2.0 schema and
    rules); empty: valid."""
    from fmpy.validation import validate_fmu

    return [str(problem) for problem in validate_fmu(str(fmu))]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="where joint.fmu and its map go")
    args = parser.parse_args(argv)
    fmu = build(args.out)
    problems = validate(fmu)
    if problems:
        print(f"joint_fmu: FMPy finds {fmu} invalid: {'; '.join(problems)}", file=sys.stderr)
        return 1
    print(f"build: the joint's FMU {fmu} (FMI 2.0 co-simulation, valid), its map {args.out / MAP_NAME}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
