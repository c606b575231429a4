"""The plant and sensors against reference trajectories recorded from the original pure-Python
implementation (commit dce737c): every float must be bit-identical, so moving the arithmetic
(to C, or anywhere else) cannot drift a single ulp without this test saying where.

The fixture holds, per scenario, one digest per block of steps plus a few full states as
float.hex, so it stays small and a failure still names the first block that differs.
Re-record only on purpose, when the physics is meant to change:
    .venv/bin/python rig/tests/test_physics_reference.py
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from collections.abc import Callable, Iterator
from pathlib import Path

from hilrig.plants import JointParams, JointPlant, SensorModel

FIXTURE = Path(__file__).parent / "data" / "physics_reference.json"
BLOCK_STEPS = 100
"""Steps per digest: a failure names the first block of this many steps that differs."""
SAMPLE_EVERY = 500
"""A full state in float.hex every this many steps, to show how far apart a failure is."""
SENSOR_SEED = 12345


@dataclasses.dataclass(frozen=True)
class Scenario:
    """A plant, its sensors and a schedule of inputs and disturbances, step by step."""

    name: str
    make_plant: Callable[[], JointPlant]
    steps: int
    drive: Callable[[JointPlant, int], tuple[float, float, float]]
    """(plant, step index) -> (dt_s, duty, load_torque_nm); may also disturb the plant."""


def _drive_default(plant: JointPlant, i: int) -> tuple[float, float, float]:
    # Held rotor for a while, a hotter enclosure later, a push on the load in between.
    if i == 1200:
        plant.set_motor_held(True)
    if i == 1500:
        plant.set_motor_held(False)
    if i == 2000:
        plant.set_ambient_temperature(60.0)
    dt_s = 1e-3
    if 2500 <= i < 2520:
        dt_s = 0.25e-3  # fewer sub-steps
    elif 2520 <= i < 2530:
        dt_s = 7e-3  # many sub-steps
    if i < 400:
        duty = 0.8 * math.sin(i * 0.01)
    elif i < 600:
        duty = 1.5 if i % 50 < 25 else -2.0  # clamped by the H-bridge
    elif i < 1000:
        duty = 0.0  # shorted winding brakes the rotor
    else:
        duty = 0.3 + 0.2 * math.cos(i * 0.003)
    load_torque_nm = 0.3 * math.sin(i * 0.02) if 800 <= i < 1800 else 0.0
    return dt_s, duty, load_torque_nm


def _drive_heating(plant: JointPlant, i: int) -> tuple[float, float, float]:
    # Fast thermal mass: R climbs with temperature, so the L/R sub-step limit moves.
    if i == 1000:
        plant.set_motor_held(True)
    if i == 2500:
        plant.set_ambient_temperature(-10.0)
    duty = 0.9 if i < 2000 else -0.5
    return 1e-3, duty, -0.1 if i % 700 < 100 else 0.0


def _drive_adiabatic(plant: JointPlant, i: int) -> tuple[float, float, float]:
    if i == 300:
        plant.set_motor_held(False)
    duty = -0.6 if (i // 150) % 2 else 0.7
    return (2e-3 if i % 3 else 0.5e-3), duty, 0.05 * math.cos(i * 0.05)


SCENARIOS = (
    Scenario("default", lambda: JointPlant(JointParams()), 3000, _drive_default),
    Scenario("fast_thermal", lambda: JointPlant(JointParams.fast_thermal()), 3000, _drive_heating),
    Scenario(
        "adiabatic_from_motion",
        lambda: JointPlant(
            dataclasses.replace(
                JointParams(),
                winding_thermal_resistance_k_per_w=math.inf,
                copper_temperature_coefficient_per_k=0.02,
                spring_stiffness_nm_per_rad=120.0,
                load_coulomb_friction_nm=0.2,
            ),
            motor_angle_rad=-3.7,
            motor_velocity_rad_s=150.0,
            load_angle_rad=-0.2,
            load_velocity_rad_s=-1.5,
            current_a=2.5,
            winding_temperature_c=80.0,
            motor_held=True,
        ),
        1500,
        _drive_adiabatic,
    ),
)


def _trajectory(scenario: Scenario) -> Iterator[list[str]]:
    """Per step: the returned JointState, max_substep_s() and the sensor frame, as text."""
    plant = scenario.make_plant()
    sensors = SensorModel(plant.params, SENSOR_SEED)
    for i in range(scenario.steps):
        dt_s, duty, load_torque_nm = scenario.drive(plant, i)
        state = plant.step(dt_s, duty, load_torque_nm)
        raw = sensors.read(plant.state)
        yield (
            [float(getattr(state, f.name)).hex() for f in dataclasses.fields(state)]
            + [plant.max_substep_s().hex()]
            + [str(getattr(raw, f.name)) for f in dataclasses.fields(raw)]
        )


def _digest(rows: list[list[str]]) -> str:
    return hashlib.sha256("\n".join(" ".join(row) for row in rows).encode()).hexdigest()[:16]


def record(scenario: Scenario) -> dict[str, object]:
    blocks: list[str] = []
    samples: dict[str, list[str]] = {}
    block: list[list[str]] = []
    for i, row in enumerate(_trajectory(scenario)):
        block.append(row)
        if i % SAMPLE_EVERY == 0 or i == scenario.steps - 1:
            samples[str(i)] = row
        if len(block) == BLOCK_STEPS:
            blocks.append(_digest(block))
            block = []
    if block:
        blocks.append(_digest(block))
    return {"steps": scenario.steps, "block_digests": blocks, "samples": samples}


def test_trajectories_are_bit_identical_to_the_recorded_reference() -> None:
    reference = json.loads(FIXTURE.read_text())
    assert reference["columns"] == _columns()
    for scenario in SCENARIOS:
        expected = reference["scenarios"][scenario.name]
        got = record(scenario)
        for index, row in expected["samples"].items():
            assert got["samples"][index] == row, f"{scenario.name}: step {index} differs"
        digests = zip(expected["block_digests"], got["block_digests"], strict=True)
        for block, (want, have) in enumerate(digests):
            first = block * BLOCK_STEPS
            assert have == want, f"{scenario.name}: steps {first}..{first + BLOCK_STEPS - 1} differ"


def _columns() -> list[str]:
    state = JointPlant().state
    raw = SensorModel(JointParams(), 0).read(state)
    return (
        [f.name for f in dataclasses.fields(state)]
        + ["max_substep_s"]
        + [f.name for f in dataclasses.fields(raw)]
    )


if __name__ == "__main__":
    FIXTURE.parent.mkdir(exist_ok=True)
    fixture = {
        "columns": _columns(),
        "scenarios": {scenario.name: record(scenario) for scenario in SCENARIOS},
    }
    FIXTURE.write_text(json.dumps(fixture, indent=1) + "\n")
    print(f"wrote {FIXTURE} ({FIXTURE.stat().st_size} bytes)")
