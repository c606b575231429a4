"""`hilrig new-board`'s project (hilrig.apps.scaffold): every file written and filled in, its
table loads, its plant is a plant that runs, and the folder is written whole or not at all. That
its firmware builds and its scenario passes on the bus is tools/new_user.py's (make test)."""

from __future__ import annotations

import importlib.util
import math
import re
from pathlib import Path

import pytest

from boardproto import load_table
from hilrig.apps import scaffold
from hilrig.cli import main
from hilrig.plants.interface import Plant

EXPECTED = {
    "board.toml",
    "CMakeLists.txt",
    "firmware/main.cpp",
    "firmware/components.hpp",
    "fan_plant.py",
    "pytest.ini",
    "test_fan.py",
    "README.md",
    ".gitignore",
    ".github/workflows/hil.yml",
}


def test_new_board_writes_the_whole_project(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["new-board", "fan", "--dir", str(tmp_path / "fan"), "--node-id", "0x21"]) == 0
    project = tmp_path / "fan"
    written = {str(path.relative_to(project)) for path in project.rglob("*") if path.is_file()}
    assert written == EXPECTED
    for name in written:
        text = (project / name).read_text()
        assert not re.search(r"\{\{\w+\}\}", text), f"{name}: a placeholder is left"
    assert "fan/" in capsys.readouterr().out
    table = load_table(project / "board.toml")
    assert table.node.device_name == "fan"
    assert table.node.default_node_id == 0x21
    assert table.node.product_code == scaffold.product_code_of("fan")
    assert "fan-firmware" in (project / "pytest.ini").read_text()


def test_two_boards_get_two_identities() -> None:
    assert scaffold.product_code_of("fan") != scaffold.product_code_of("pump")


def _plant_module(project: Path, board: str) -> object:
    spec = importlib.util.spec_from_file_location(f"{board}_plant", project / f"{board}_plant.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_plant_is_a_deterministic_plant_of_the_table(tmp_path: Path) -> None:
    project = tmp_path / "pump"
    scaffold.new_board("pump", project)
    table = load_table(project / "board.toml")
    module = _plant_module(project, "pump")

    def run(seed: int) -> list[object]:
        plant = module.make_plant(None, seed)  # type: ignore[attr-defined]
        assert isinstance(plant, Plant)
        assert set(plant.sensor_fields) <= {io.name for io in table.hil_inputs}
        assert set(plant.actuator_fields) <= {io.name for io in table.hil_outputs}
        frames = []
        for _ in range(500):
            frames.append(plant.sense())
            plant.apply([6000])
            plant.step(1e-3)
        assert math.isclose(plant.truth()[0], 0.6, abs_tol=0.01)  # 10 time constants: settled
        assert plant.truth_matrix([plant.truth(), plant.truth()]).shape == (2, 1)
        return frames

    assert run(1) == run(1)
    assert run(1) != run(2)


def test_a_folder_in_the_way_is_refused_and_left_as_it_was(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "fan").mkdir()
    (tmp_path / "fan" / "notes.txt").write_text("mine")
    assert main(["new-board", "fan", "--dir", str(tmp_path / "fan")]) == 2
    assert "not an empty folder" in capsys.readouterr().err
    assert [p.name for p in (tmp_path / "fan").iterdir()] == ["notes.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fan"]  # no staging folder left


@pytest.mark.parametrize("name", ["Fan", "2fan", "fan-controller", ""])
def test_a_name_that_is_no_identifier_is_refused(
    name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["new-board", name, "--dir", str(tmp_path / "x")]) == 2
    assert "lower-case letters" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_an_error_while_writing_leaves_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def fail(*args: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(scaffold.Path, "rename", fail)
    with pytest.raises(KeyboardInterrupt):
        scaffold.new_board("fan", tmp_path / "fan")
    assert list(tmp_path.iterdir()) == []
