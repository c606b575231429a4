"""The installable hilrig: what `make dist` writes (tools/dist.py: the sdist, and the wheel built
from it), installed into fresh virtual environments outside the checkout, run from a directory
that is not the checkout: what a user without the checkout gets.

`pip install --no-index --find-links DIST hilrig`, DIST holding only what `make dist` wrote;
hilrig's dependencies come from the project venv through a .pth file naming a directory of links
to its site-packages, minus hilrig, boardproto and dashboards (editable installs of the checkout
there), so nothing is downloaded and every import of hilrig is the wheel's. The same check for a
second wheel built here from the sdist. Nothing may name a package the index could supply in our
place: only hilrig in DIST and in the environment, no requirement but the third-party packages
requirements.lock pins.
"""

from __future__ import annotations

import importlib.util
import os
import re
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
_SPEC = importlib.util.spec_from_file_location("dist_tool", REPO / "tools" / "dist.py")
assert _SPEC is not None and _SPEC.loader is not None
dist = importlib.util.module_from_spec(_SPEC)  # tools/dist.py: the wheel of the sdist, as `make dist`
_SPEC.loader.exec_module(dist)

OWN_PACKAGES = ("hilrig", "boardproto", "dashboards")
NOT_DEPENDENCIES = (*OWN_PACKAGES, "__editable__", "__pycache__")
"""Entries of the project venv's site-packages the test venv must not see (prefixes)."""


@dataclass(frozen=True)
class Installed:
    wheel: Path
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
    if into.is_dir():
        return into
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


def _install(root: Path, found_in: Path, name: str) -> Installed:
    """`pip install --no-index --find-links FOUND_IN hilrig` into a fresh venv `root`/`name`."""
    venv = root / name
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", venv], check=True, timeout=60)
    site_packages = subprocess.run(
        [venv / "bin" / "python", "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    dependencies = _project_dependencies(root / "dependencies")
    (Path(site_packages) / "project-dependencies.pth").write_text(f"{dependencies}\n")
    pip = [sys.executable, "-m", "pip", "--python", venv / "bin" / "python", "--disable-pip-version-check"]
    install = [*pip, "install", "--quiet", "--no-index", "--find-links", found_in, "hilrig"]
    done = subprocess.run(install, capture_output=True, text=True, check=False, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
    checked = subprocess.run([*pip, "check"], capture_output=True, text=True, check=False, timeout=60)
    assert checked.returncode == 0, checked.stdout + checked.stderr
    own = sorted(p.name for p in Path(site_packages).iterdir() if p.name != "project-dependencies.pth")
    assert own == ["hilrig", "hilrig-0.1.0.dist-info"], own  # no top-level name but hilrig
    (wheel,) = found_in.glob("hilrig-*.whl")
    workdir = root / f"{name}-work"
    workdir.mkdir()
    return Installed(wheel, venv, workdir, _clean_env(venv, root))


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """DIST as `make dist` writes it (tools/dist.py, run outside the checkout's environment)."""
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
    return root / "dist"


@pytest.fixture(scope="module")
def installed(built: Path) -> Installed:
    return _install(built.parent, built, "venv")


def test_dist_holds_hilrig_alone_requiring_only_what_the_lock_pins(built: Path) -> None:
    assert sorted(p.name for p in built.iterdir()) == [
        "hilrig-0.1.0-cp311-abi3-linux_x86_64.whl",  # CPython 3.11 and later (limited API)
        "hilrig-0.1.0.tar.gz",
    ]
    (wheel,) = built.glob("*.whl")
    with zipfile.ZipFile(wheel) as archive:
        metadata = archive.read("hilrig-0.1.0.dist-info/METADATA").decode()
        top_level = {name.split("/")[0] for name in archive.namelist()}
    assert top_level == {"hilrig", "hilrig-0.1.0.dist-info"}
    required = {
        re.split(r"[\s\[<>=~;!]", line.split(":", 1)[1].strip())[0].lower()
        for line in metadata.splitlines()
        if line.startswith("Requires-Dist:")
    }
    pinned = {
        line.split("==")[0].strip().lower()
        for line in (REPO / "requirements.lock").read_text().splitlines()
        if "==" in line and not line.startswith("#")
    }
    assert not required & set(OWN_PACKAGES)
    assert required <= pinned, f"not in requirements.lock: {sorted(required - pinned)}"


def test_the_pytest_extra_brings_what_a_scenario_author_and_a_failure_report_need(built: Path) -> None:
    (wheel,) = built.glob("*.whl")
    with zipfile.ZipFile(wheel) as archive:
        metadata = archive.read("hilrig-0.1.0.dist-info/METADATA").decode()
    assert "Provides-Extra: pytest" in metadata
    extra = {
        re.split(r"[\s\[<>=~;!]", line.split(":", 1)[1].strip())[0].lower()
        for line in metadata.splitlines()
        if line.startswith("Requires-Dist:") and line.endswith('extra == "pytest"')
    }
    assert extra == {"pytest", "matplotlib", "pytest-xdist", "pytest-timeout"}


def test_the_wheel_holds_every_module_the_table_its_eds_and_dbc_and_the_dashboards(
    installed: Installed,
) -> None:
    names = set(zipfile.ZipFile(installed.wheel).namelist())
    sources = (
        {path.relative_to(REPO / "rig").as_posix() for path in (REPO / "rig" / "hilrig").rglob("*.py")}
        | {f"hilrig/dashboards/{path.name}" for path in (REPO / "dashboards").glob("*.py")}
        | {f"hilrig/boardproto/{path.name}" for path in (REPO / "protocol" / "boardproto").glob("*.py")}
    )
    assert sources <= names, f"left out of the wheel: {sorted(sources - names)}"
    assert {"hilrig/data/board.toml", "hilrig/data/board.eds", "hilrig/data/board.dbc"} <= names
    for extension in ("hilrig/plants/_plant.", "hilrig/wire/_wire."):
        assert f"{extension}abi3.so" in names, extension  # the stable ABI: any CPython 3.11+
    assert not any("/tests/" in name or name.endswith(".c") for name in names)


def test_hilrig_and_its_generators_and_dashboards_are_the_wheels_not_the_checkout(
    installed: Installed,
) -> None:
    probe = installed.run(
        installed.venv / "bin" / "python",
        "-c",
        "import hilrig, hilrig.boardproto, hilrig.dashboards, hilrig.resources as r\n"
        "for module in (hilrig.boardproto, hilrig.dashboards, hilrig): print(module.__file__)\n"
        "print(r.CHECKOUT, r.DEFAULT_TABLE.is_file(), r.DEFAULT_EDS.is_file(), r.DEFAULT_DBC.is_file())\n"
        "import importlib.util\n"
        "print([n for n in ('boardproto', 'dashboards') if importlib.util.find_spec(n)])",
    )
    assert probe.returncode == 0, probe.stderr
    *files, resolution, top_level = probe.stdout.splitlines()
    site_packages = installed.venv.resolve() / "lib"
    assert all(Path(file).resolve().is_relative_to(site_packages) for file in files), files
    assert resolution == "None True True True"
    assert top_level == "[]"


def test_the_sdist_builds_a_wheel_that_installs_and_runs(built: Path) -> None:
    again = built.parent / "from-sdist"
    again.mkdir()
    dist.build_wheel(built / "hilrig-0.1.0.tar.gz", again)
    installed = _install(built.parent, again, "venv-sdist")
    version = installed.hilrig("--version")
    assert version.returncode == 0, version.stderr
    assert version.stdout.startswith("hilrig 0.1.0 (python-can "), version.stdout
    fields = installed.hilrig("fields", "motor_velocity")
    assert fields.returncode == 0 and "motor_velocity" in fields.stdout, fields.stderr


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
    dashboards = installed.run(installed.venv / "bin" / "python", "-m", "hilrig.dashboards", "--help")
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


def test_the_installed_pytest_plugin_serves_a_project_outside_the_checkout(installed: Installed) -> None:
    # A project of its own: its table (the demo's with a field renamed), its plant module, its
    # pytest.ini naming them; the fixtures come from the wheel's entry point, the EDS is
    # generated from the table by the wheel's boardproto.
    project = installed.workdir / "project"
    project.mkdir()
    text = (REPO / "protocol" / "board.toml").read_text()
    (project / "board.toml").write_text(text.replace('"motor_duty"', '"motor_pwm"'))
    (project / "pytest.ini").write_text(
        "[pytest]\nhil_table = board.toml\nhil_firmware = bin/firmware\nhil_plant = my_plant:make\n"
    )
    (project / "my_plant.py").write_text(
        "from hilrig.plants.joint import JointModel\n\n\ndef make(params, seed):\n"
        "    return JointModel.of(params, seed)\n"
    )
    (project / "test_board.py").write_text(
        "from pathlib import Path\n\nimport hilrig\n\n\ndef test_board(hil_board, make_scenario):\n"
        "    assert 'site-packages' in hilrig.__file__\n"
        "    assert 'motor_pwm' in hil_board.table.names and hil_board.eds.is_file()\n"
        "    assert 'ParameterName=motor_pwm' in hil_board.eds.read_text()\n"
        "    assert hil_board.firmware == Path('bin/firmware').resolve()\n"
        "    assert hil_board.plant(None, 2).sensor_fields\n"
    )
    python = installed.venv / "bin" / "python"
    done = subprocess.run(
        [python, "-m", "pytest", "-q", "-p", "no:cacheprovider"],
        cwd=project,
        env=installed.env,
        capture_output=True,
        text=True,
        check=False,
        timeout=120,
    )
    assert done.returncode == 0 and "1 passed" in done.stdout, done.stdout + done.stderr
