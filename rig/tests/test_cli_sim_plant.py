"""`hilrig sim --plant model.fmu --plant-map map.toml [--table T]`: what it refuses, in one line
and exit code 2, before any bus or firmware is needed; the summary of a run on another board's
table. The run itself, on the bus: tests/test_joint_fmu_bus.py (the same plant factory)."""

from __future__ import annotations

from pathlib import Path

import pytest

from hilrig import resources
from hilrig.apps.demo import DemoSummary, format_summary
from hilrig.cli import EXIT_USAGE, main

pytest.importorskip("fmpy")
crane_fmu = pytest.importorskip("crane_fmu")
OSCILLATOR = Path(crane_fmu.__file__).resolve().parent.parent / "examples" / "HarmonicOscillator6D.fmu"
HEAD_MAP = Path(__file__).resolve().parents[2] / "tests" / "fmu" / "head_oscillator.map.toml"


def refused(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    code = main(["sim", *argv])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert code == EXIT_USAGE, err
    assert err.count("\n") == 1 and err.startswith("hilrig "), err
    return err


def test_an_fmu_without_its_map(capsys: pytest.CaptureFixture[str]) -> None:
    err = refused(capsys, ["--plant", str(OSCILLATOR)])
    assert "--plant-map" in err


def test_a_map_of_another_board_on_the_joints_table(capsys: pytest.CaptureFixture[str]) -> None:
    err = refused(capsys, ["--plant", str(OSCILLATOR), "--plant-map", str(HEAD_MAP)])
    assert "rail_switch" in err and "not a HIL output of the table" in err


def test_another_boards_table_needs_its_plant_firmware_and_scenario(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    head = str(resources.HEAD_TABLE)
    assert "give its plant with --plant" in refused(capsys, ["--table", head])
    given = ["--table", head, "--plant", str(OSCILLATOR), "--plant-map", str(HEAD_MAP)]
    assert "--firmware" in refused(capsys, given)
    firmware = tmp_path / "fw"
    firmware.write_bytes(b"\x7fELF")
    firmware.chmod(0o755)
    assert "--scenario" in refused(capsys, [*given, "--firmware", str(firmware)])


def test_a_plant_with_modules_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    err = refused(capsys, ["--modules", "2", "--plant", str(OSCILLATOR), "--plant-map", str(HEAD_MAP)])
    assert "--plant" in err and "--modules" in err


def test_the_summary_of_another_board_has_the_runs_rows_only(tmp_path: Path) -> None:
    run = {"cycles": 150, "simulated_s": 0.15, "wall_s": 2.0, "cycling_s": 1.0, "frames_logged": 900}
    summary = DemoSummary(
        **run,
        velocity_rms_error_rad_s=None,
        torque_rms_error_nm=None,
        spring_constant_estimate=None,
        spring_constant_confidence=None,
        spring_constant_true=None,
        peak_temperature_reported_c=None,
        peak_temperature_true_c=None,
        fault_flags=0,
        safe_state=False,
        emcy=(),
        bus_log=tmp_path / "bus.log",
        firmware_log=tmp_path / "firmware.log",
    )
    text = format_summary(summary)
    assert "150 cycles" in text and "900 frames" in text
    assert "spring constant" not in text and "tracking" not in text
