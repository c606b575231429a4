"""The installable hilrig: the wheels `make dist` builds (tools/dist.py), installed into a fresh
virtual environment outside the checkout and run from a directory that is not the checkout.

Nothing is downloaded: the test venv gets the wheels with --no-deps, and their dependencies from
the project venv through a .pth file naming a directory of links to its site-packages, minus
hilrig, boardproto and dashboards (editable installs of the checkout there). So every import of
those three comes from the wheels, which the test checks; `pip check` then says the wheels'
declared requirements are met by the versions requirements.lock pins.
"""

from __future__ import annotations

import os
import subprocess
import sys
import sysconfig
import zipfile
from dataclasses import dataclass
from pathlib import Path

import can
import pytest

from boardproto.cia301 import SYNC_COB_ID
from hilrig.table import BOARD_TABLE

REPO = Path(__file__).resolve().parents[2]
OWN_PACKAGES = ("hilrig", "boardproto", "dashboards")
NOT_DEPENDENCIES = (*OWN_PACKAGES, "__editable__", "__pycache__")
"""Entries of the project venv's site-packages the test venv must not see (prefixes)."""


@dataclass(frozen=True)
class Installed:
    wheels: list[Path]
    venv: Path
    workdir: Path
    """Where the commands run: an empty directory outside the checkout."""
    env: dict[str, str]

    def run(self, *argv: str | Path) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [str(arg) for arg in argv],
            cwd=self.workdir,
            env=self.env,
            capture_output=True,
            text=True,
            check=False,
            timeout=120,
        )

    def hilrig(self, *argv: str | Path) -> subprocess.CompletedProcess[str]:
        return self.run(self.venv / "bin" / "hilrig", *argv)


def _project_dependencies(into: Path) -> Path:
    """A directory of links to the project venv's site-packages, less hilrig and its siblings."""
    into.mkdir()
    for entry in Path(sysconfig.get_path("purelib")).iterdir():
        if entry.name.startswith(NOT_DEPENDENCIES) or entry.suffix == ".pth":
            continue
        (into / entry.name).symlink_to(entry)
    return into


def _clean_env(venv: Path, root: Path) -> dict[str, str]:
    """This process's environment without what would reach the checkout (PYTHONPATH) or the
    project venv, with the test venv first on PATH and a cache of its own."""
    env = {key: value for key, value in os.environ.items() if not key.startswith(("PYTHON", "VIRTUAL_ENV"))}
    env["PATH"] = f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    env["XDG_CACHE_HOME"] = str(root / "cache")
    return env


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> Installed:
    root = tmp_path_factory.mktemp("wheel")
    assert not root.resolve().is_relative_to(REPO)
    build = subprocess.run(
        [sys.executable, REPO / "tools" / "dist.py", "--out", root / "dist"],
        env=_clean_env(root / "none", root),
        capture_output=True,
        text=True,
        check=False,
        timeout=300,
    )
    assert build.returncode == 0, build.stderr
    wheels = sorted((root / "dist").glob("*.whl"))
    assert [wheel.name.split("-")[0] for wheel in wheels] == ["boardproto", "hilrig"]
    venv = root / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", venv], check=True, timeout=60)
    pip = [sys.executable, "-m", "pip", "--python", venv / "bin" / "python"]
    subprocess.run([*pip, "install", "--quiet", "--no-deps", "--no-index", *wheels], check=True, timeout=120)
    site_packages = subprocess.run(
        [venv / "bin" / "python", "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    dependencies = _project_dependencies(root / "dependencies")
    (Path(site_packages) / "project-dependencies.pth").write_text(f"{dependencies}\n")
    checked = subprocess.run([*pip, "check"], capture_output=True, text=True, check=False, timeout=60)
    assert checked.returncode == 0, checked.stdout + checked.stderr
    workdir = root / "work"
    workdir.mkdir()
    return Installed(wheels, venv, workdir, _clean_env(venv, root))


def test_the_wheel_holds_every_module_the_table_its_eds_and_dbc_and_the_dashboards(
    installed: Installed,
) -> None:
    hilrig_wheel = installed.wheels[1]
    names = set(zipfile.ZipFile(hilrig_wheel).namelist())
    sources = {
        path.relative_to(REPO / "rig").as_posix() for path in (REPO / "rig" / "hilrig").rglob("*.py")
    } | {path.relative_to(REPO).as_posix() for path in (REPO / "dashboards").glob("*.py")}
    assert sources <= names, f"left out of the wheel: {sorted(sources - names)}"
    assert {"hilrig/data/board.toml", "hilrig/data/board.eds", "hilrig/data/board.dbc"} <= names
    for extension in ("hilrig/plants/_plant.", "hilrig/wire/_wire."):
        assert any(name.startswith(extension) and name.endswith(".so") for name in names), extension
    assert not any("/tests/" in name or name.endswith(".c") for name in names)


def test_hilrig_dashboards_and_boardproto_are_the_wheels_not_the_checkout(installed: Installed) -> None:
    probe = installed.run(
        installed.venv / "bin" / "python",
        "-c",
        "import boardproto, dashboards, hilrig, hilrig.resources as r\n"
        "for module in (boardproto, dashboards, hilrig): print(module.__file__)\n"
        "print(r.CHECKOUT, r.DEFAULT_TABLE.is_file(), r.DEFAULT_EDS.is_file(), r.DEFAULT_DBC.is_file())",
    )
    assert probe.returncode == 0, probe.stderr
    *files, resolution = probe.stdout.splitlines()
    site_packages = installed.venv.resolve() / "lib"
    assert all(Path(file).resolve().is_relative_to(site_packages) for file in files), files
    assert resolution == "None True True True"


def test_version_fields_and_sdo_help_run_from_anywhere(installed: Installed) -> None:
    version = installed.hilrig("--version")
    assert version.returncode == 0, version.stderr
    assert version.stdout.startswith("hilrig 0.1.0 (python-can "), version.stdout
    assert "not installed" not in version.stdout
    fields = installed.hilrig("fields")
    assert fields.returncode == 0, fields.stderr
    listed = [line.split()[0] for line in fields.stdout.splitlines()[1:]]
    assert listed == [entry.name for entry in BOARD_TABLE.entries]
    sdo = installed.hilrig("sdo", "--help")
    assert sdo.returncode == 0, sdo.stderr
    assert "read" in sdo.stdout and "write" in sdo.stdout
    dashboards = installed.run(installed.venv / "bin" / "python", "-m", "dashboards", "--help")
    assert dashboards.returncode == 0, dashboards.stderr
    assert "overview" in dashboards.stdout


def test_replay_decodes_with_the_packaged_dbc_and_with_one_generated_for_another_table(
    installed: Installed,
) -> None:
    log = installed.workdir / "bus.log"
    node = BOARD_TABLE.node.default_node_id
    with can.Logger(str(log)) as logger:
        logger(can.Message(timestamp=1.0, arbitration_id=SYNC_COB_ID, data=bytes([1]), is_extended_id=False))
        tpdo1 = BOARD_TABLE.tpdo(1).cob_id(node)
        logger(can.Message(timestamp=1.001, arbitration_id=tpdo1, data=bytes(3), is_extended_id=False))
    replay = installed.hilrig("replay", "bus.log", "--decode")
    assert (replay.returncode, replay.stderr) == (0, "")
    lines = replay.stdout.splitlines()
    assert len(lines) == 2 and "SYNC 1" in lines[0]
    assert f"0x{tpdo1:03X}  TPDO1  motor_duty=0 0.01%" in lines[1]

    table = installed.workdir / "other-board.toml"
    table.write_text((REPO / "protocol" / "board.toml").read_text().replace('"motor_duty"', '"motor_pwm"'))
    replay = installed.hilrig("replay", "bus.log", "--decode", "--table", table.name)
    assert (replay.returncode, replay.stderr) == (0, "")
    assert "TPDO1  motor_pwm=0 0.01%" in replay.stdout
    generated = list((Path(installed.env["XDG_CACHE_HOME"]) / "hilrig" / "tables").glob("*/board.dbc"))
    assert len(generated) == 1
