"""The FMU plant over a published FMU (crane-fmu's HarmonicOscillator6D, FMI 2.0 co-simulation)
on the robot head's table: the map's checks, one step per period, truth and determinism."""

from __future__ import annotations

from pathlib import Path

import pytest

from hilrig import resources
from hilrig.errors import PlantMapError
from hilrig.plants.fmu import FmuPlant, fmu_factory
from hilrig.plants.fmu_map import load_map
from hilrig.plants.interface import Plant
from hilrig.table import RigTable

pytest.importorskip("fmpy")
crane_fmu = pytest.importorskip("crane_fmu")

FMU = Path(crane_fmu.__file__).resolve().parent.parent / "examples" / "HarmonicOscillator6D.fmu"
MAP = Path(__file__).resolve().parents[2] / "tests" / "fmu" / "head_oscillator.map.toml"
HEAD = RigTable.load(resources.HEAD_TABLE).board


@pytest.fixture(scope="module")
def make():
    return fmu_factory(MAP, HEAD, FMU)


def test_the_plant_follows_the_fmu_once_per_period(make) -> None:
    plant = make(None, 1)
    assert isinstance(plant, Plant)
    assert plant.actuator_fields == ("rail_switch",)
    assert set(plant.sensor_fields) == {io.name for io in HEAD.hil_inputs}
    assert plant.truth_fields == ("pitch_rate_rad_s", "pitch_rad")
    assert plant.truth_parameters() == {"k[4]": 1600.0, "c[4]": 8.0, "m[4]": 1.0}
    assert plant.truth() == (0.0, 0.0)
    plant.apply([1])  # the rail on: 160 N.m on a 1600 N.m/rad spring, 0.1 rad at rest
    rows = []
    for _ in range(600):
        rows.append(plant.truth())
        plant.step(1e-3)
    assert plant.time_s == pytest.approx(0.6)
    pitch = plant.truth_matrix(rows)[:, 1]
    assert pitch.max() > 0.15  # overshoot of a lightly damped mount
    assert plant.truth()[1] == pytest.approx(0.1, abs=0.01)
    frame = plant.sense()
    assert frame.battery_adc == 12000 and frame.accel_z_counts == 4097
    assert abs(frame.gyro_y_counts - round(plant.truth()[0] * 939.65)) <= 5


def test_the_same_seed_gives_the_same_frames_and_another_seed_other_noise(make) -> None:
    def run(seed: int) -> list[int]:
        plant = make(None, seed)
        plant.apply([1])
        frames = []
        for _ in range(10):
            frames.append(plant.sense().gyro_y_counts)
            plant.step(1e-3)
        return frames

    assert run(3) == run(3)
    assert run(3) != run(4)


def test_params_set_fmu_parameters_and_substeps_split_the_period(make, tmp_path) -> None:
    stiff = make({"k[4]": 6400.0}, 1)
    stiff.apply([1])
    for _ in range(300):
        stiff.step(1e-3)
    assert stiff.truth()[1] == pytest.approx(160.0 / 6400.0, abs=0.005)
    with pytest.raises(PlantMapError, match=r"no parameter 'k\[9\]'"):
        make({"k[9]": 1.0}, 1)
    halves = tmp_path / "halves.map.toml"
    halves.write_text("substeps = 2\n" + MAP.read_text(encoding="utf-8").replace("substeps = 1\n", ""))
    fine = FmuPlant.load(halves, HEAD, FMU)
    assert fine.map.substeps == 2
    fine.apply([1])
    fine.step(1e-3)
    assert fine.time_s == pytest.approx(1e-3) and fine.truth()[1] > 0.0


def test_an_fmu_that_cannot_save_its_state_says_to_rerun(make) -> None:
    with pytest.raises(PlantMapError, match="running again from the same seed"):
        make(None, 1).save_state()


@pytest.mark.parametrize(
    ("old", "new", "error"),
    [
        (
            'variable = "f[4]"',
            'variable = "f[9]"',
            r"\[\[input\]\] #1: the FMU HarmonicOscillator6D.fmu has no variable 'f\[9\]'",
        ),
        ('variable = "f[4]"', 'variable = "x[4]"', r"x\[4\] is an FMU output, expected input"),
        (
            'variable = "v[4]"',
            'variable = "f[1]"',
            r"\[\[output\]\] #1: f\[1\] is an FMU input, expected output",
        ),
        ('field = "rail_switch"', 'field = "led_red"', r"'led_red' is not a HIL output of the table"),
        ('field_unit = "count"', 'field_unit = "rad/s"', r"gyro_y_counts is in count in the table"),
        (
            'field = "battery_adc"',
            'field = "gyro_y_counts"',
            r"\['gyro_y_counts'\] have more than one source",
        ),
        ('"c[4]" = 8.0', '"v[4]" = 8.0', r"\[parameters\]: v\[4\] is an FMU output, not a parameter"),
        ("substeps = 1", "substeps = 0", "substeps must be an integer >= 1"),
    ],
)
def test_a_map_that_does_not_fit_is_a_one_line_error(tmp_path, old, new, error) -> None:
    text = MAP.read_text(encoding="utf-8")
    assert old in text
    broken = tmp_path / "broken.map.toml"
    broken.write_text(text.replace(old, new, 1))
    with pytest.raises(PlantMapError, match=error) as raised:
        load_map(broken, HEAD, FMU)
    assert "\n" not in str(raised.value)


def test_a_unit_the_fmu_does_not_declare_and_a_missing_source_are_errors(tmp_path) -> None:
    text = MAP.read_text(encoding="utf-8")
    wrong_unit = tmp_path / "unit.map.toml"
    wrong_unit.write_text(text.replace('unit = "dimensionless"', 'unit = "N.m"', 1))
    with pytest.raises(PlantMapError, match=r"f\[4\] is in dimensionless in the FMU, the map says 'N.m'"):
        load_map(wrong_unit, HEAD, FMU)
    no_battery = tmp_path / "source.map.toml"
    no_battery.write_text(
        text.replace('field = "battery_adc"\nvalue = 12000', 'field = "accel_x_counts"\nvalue = 1')
    )
    with pytest.raises(PlantMapError, match=r"HIL input\(s\) \['battery_adc'\] have no source"):
        load_map(no_battery, HEAD, FMU)
    with pytest.raises(PlantMapError, match="names no fmu"):
        load_map(MAP, HEAD)
    with pytest.raises(PlantMapError, match="no such file"):
        load_map(MAP, HEAD, tmp_path / "none.fmu")


def test_the_pytest_plugin_takes_an_fmu_and_its_map() -> None:
    from hilrig.pytest_plugin.board import fmu_plant_factory

    table = RigTable.load(resources.HEAD_TABLE)
    assert callable(fmu_plant_factory(FMU, MAP, table))
    with pytest.raises(pytest.UsageError, match="an FMU needs hil_plant_map"):
        fmu_plant_factory(FMU, None, table)
    with pytest.raises(pytest.UsageError, match="names no fmu"):
        fmu_plant_factory(None, MAP, table)
