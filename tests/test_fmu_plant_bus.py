"""The robot head's firmware on its private bus against an FMU nobody here wrote: crane-fmu's
HarmonicOscillator6D (a published FMI 2.0 co-simulation FMU) as the head's spring mount, tied to
the head's HIL I/O by tests/fmu/head_oscillator.map.toml. The rail's switch (the firmware's
output) drives the FMU's pitch torque; the FMU's pitch rate comes back as the IMU's gyro, which
the firmware publishes. Lockstep, simulation time, one doStep per SYNC."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import HEAD_MAPPING_ON_THE_IDEAL_BUS

from hilrig import resources
from hilrig.plants.fmu import fmu_factory
from hilrig.pytest_plugin.board import HilBoard
from hilrig.table import RigTable

pytestmark = [pytest.mark.bus, HEAD_MAPPING_ON_THE_IDEAL_BUS]

crane_fmu = pytest.importorskip("crane_fmu")
FMU = Path(crane_fmu.__file__).resolve().parent.parent / "examples" / "HarmonicOscillator6D.fmu"
MAP = Path(__file__).resolve().parent / "fmu" / "head_oscillator.map.toml"
HEAD = RigTable.load(resources.HEAD_TABLE)
GYRO_SCALE = float(HEAD.field("gyro_scale").default)


@pytest.fixture
def hil_board() -> HilBoard:
    """The head's table, EDS and firmware, with the FMU as its plant."""
    return HilBoard(
        table=HEAD,
        eds=resources.board_files(resources.HEAD_TABLE).eds,
        firmware=resources.HEAD_FIRMWARE,
        plant=fmu_factory(MAP, HEAD.board, FMU),
        dashboard="head",
    )


def test_the_head_closes_its_rail_and_reads_the_fmu_mount_nodding(make_scenario) -> None:
    s = make_scenario(seed=5)
    s.rig.run(seconds=0.15)  # the rail closes at start-up: 160 N.m on the mount's pitch
    _, rail = s.rig.history("rail_switch")
    assert rail[-1] == 1
    _, pitch = s.rig.truth("pitch_rad")
    assert pitch.max() > 0.15, "160 N.m on the 1600 N.m/rad mount overshoots its 0.1 rad"
    t_rate, rate = s.rig.truth("pitch_rate_rad_s")
    t_gyro, gyro = s.rig.history("gyro_y")
    assert np.abs(rate).max() > 1.0
    # The firmware's gyro_y is the FMU's rate, quantised by the IMU's scale, noise of a count.
    seen = np.interp(t_gyro, t_rate, rate)
    error = np.abs(gyro - seen).max()
    assert error < 0.02 * np.abs(rate).max() + 5 * GYRO_SCALE, f"gyro_y off the FMU's rate by {error}"

    s.rig.set("rail_enable", 0.0)  # the rail opens: no torque, the mount swings back to 0 rad
    opened_at = s.rig.t
    s.rig.run(seconds=0.15)
    _, rail = s.rig.history("rail_switch")
    assert rail[-1] == 0
    t_pitch, pitch = s.rig.truth("pitch_rad")
    late = pitch[t_pitch > opened_at + 0.05]
    assert late.min() < 0.0 < late.max(), "around 0 rad, not 0.1 rad, once the torque is off"
    assert abs(late.mean()) < 0.05, f"mean pitch {late.mean()} with the rail open"
