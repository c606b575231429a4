"""The joint demo's firmware on its private bus against the joint's own FMU (build/fmu/joint.fmu,
exported by `make build`, through build/fmu/joint.map.toml) and against the rig's native joint:
the same trace, bit for bit: every TPDO field the firmware sent, every sensor value the rig sent,
the plant's truth. One difference, made explicit: the native joint runs without sensor noise
here, because the FMU has none (its map could add the plant's own seeded noise, which is another
stream than the native sensors' numpy one, so the two would differ by their noise)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import FULL_MAPPING_ON_THE_IDEAL_BUS

from hilrig import resources
from hilrig.apps.demo import demo_params
from hilrig.plants.joint import JointModel
from hilrig.pytest_plugin.board import HilBoard
from hilrig.table import BOARD_TABLE, ControlMode

pytestmark = [pytest.mark.bus, FULL_MAPPING_ON_THE_IDEAL_BUS]

pytest.importorskip("fmpy")
from hilrig.plants.fmu import FmuPlant  # noqa: E402

NOISELESS = dataclasses.replace(demo_params(), thermistor_adc_noise_counts=0.0, current_sensor_noise_a=0.0)
Series = tuple[np.ndarray, np.ndarray]


def native_or_fmu(params: object | None, seed: int) -> JointModel | FmuPlant:
    """The scenario's plant: params "fmu" the joint's FMU, else the native joint (no noise)."""
    if params == "fmu":
        return FmuPlant.load(resources.JOINT_FMU_MAP, BOARD_TABLE, seed=seed)
    return JointModel.of(NOISELESS, seed)


@pytest.fixture
def hil_board(hil_board: HilBoard) -> HilBoard:
    assert resources.JOINT_FMU_MAP.is_file(), f"no {resources.JOINT_FMU_MAP}: run `make build`"
    return dataclasses.replace(hil_board, plant=native_or_fmu)


def record_run(make_scenario, plant: str) -> dict[str, Series]:
    """The demo's velocity then torque profile, shortened; every series the run recorded."""
    s = make_scenario(params=plant, seed=4, subdir=plant, trace=False)
    s.rig.set("control_mode", ControlMode.VELOCITY)
    s.rig.set("velocity_setpoint", 3.0)
    s.rig.run(seconds=0.2)
    s.rig.set("velocity_setpoint", -2.0)
    s.rig.run(seconds=0.1)
    s.rig.set("control_mode", ControlMode.TORQUE)
    s.rig.set("torque_setpoint", 1.0)
    s.rig.run(seconds=0.15)
    received = s.rig.driver.tpdo_names()
    sent = {n for p in s.rig.node.rpdos.values() if p.enabled for n in p.names}
    series = {f"tpdo:{name}": s.rig.history(name) for name in sorted(received)}
    series |= {f"rpdo:{name}": s.rig.sent(name) for name in sorted(sent)}
    series |= {f"truth:{name}": s.rig.truth(name) for name in JointModel.truth_fields}
    s.close()
    return series


def test_the_joint_demo_on_its_own_fmu_gives_the_native_plants_trace(make_scenario) -> None:
    native = record_run(make_scenario, "native")
    fmu = record_run(make_scenario, "fmu")
    assert native.keys() == fmu.keys()
    differing = [
        name
        for name in native
        if not (
            np.array_equal(native[name][0], fmu[name][0]) and np.array_equal(native[name][1], fmu[name][1])
        )
    ]
    assert not differing, f"the FMU's run differs from the native plant's in {differing}"
    _, velocity = native["tpdo:motor_velocity"]
    assert velocity.max() > 30.0, "the motor ran up (the run drove the joint)"
    _, duty = native["tpdo:motor_duty"]
    assert duty.min() < 0 < duty.max()
