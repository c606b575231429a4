"""Other projects than this checkout, as their users make them, outside the checkout: hilrig's
wheel (`make dist`) installed with its `pytest` extra into a fresh venv, hil-rig's firmware
package installed from the CMake build (`make hilfw`'s `cmake --install build --component
hilfw`), and three projects built against that prefix with the wheel's generator:

- lamp: a copy of examples/other-project;
- sensor_board: what `hilrig new-board sensor_board` writes, as generated;
- fan: examples/fan, which is `hilrig new-board fan` and a new user's edits (a second sensor, a
  controller, a plant, two scenarios). Those edits are counted against the scaffold the wheel
  writes now (difflib): the controller, the plant and the scenario at most MAX_USER_LINES, and
  every file the user does not edit must be the scaffold's unchanged.

Each project's scenarios then run by the wheel's own `hilrig bus -- python -m pytest` in its
folder, with no PYTHONPATH, and the wheel's `hilrig view --check` reads one of its traces (the
dashboard generated from its table and plant draws every series). Passes only if each pytest
header names the project's own firmware (hil_firmware of its pytest.ini).

    .venv/bin/python tools/other_project.py run [--uml] [PYTEST_ARGS...]

The wheel goes under build/other-project/dist; the rest under OUTSIDE (one folder per checkout,
$HIL_OTHER_PROJECT_DIR to choose another): OUTSIDE/venv, OUTSIDE/prefix, a folder per project
(with its build tree build/, which its pytest.ini names). The venv is an installer's own install
of the wheel (uv's, as tools/deps uses it, else pip's), nothing of the checkout's venv in it.
`tools/run-tests` runs it in its bus stage.
"""

from __future__ import annotations

import argparse
import difflib
import hashlib
import os
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
EXAMPLE = REPO / "examples" / "other-project"
OUT = REPO / "build" / "other-project"
OUTSIDE = Path(
    os.environ.get("HIL_OTHER_PROJECT_DIR")
    or Path(tempfile.gettempdir()) / f"hilrig-other-project-{hashlib.sha256(bytes(REPO)).hexdigest()[:8]}"
)
"""Outside the checkout, one per checkout (two clones' `make test` side by side never share it)."""
CMAKE_BUILD = Path(os.environ.get("HILFW_BUILD", REPO / "build"))
"""The configured CMake build tree whose install rules hold the firmware package: `make build`'s,
or $HILFW_BUILD (a tree configured by hand, e.g. a worktree whose build/ links another's)."""


def _run(argv: list[str | Path], **kwargs: object) -> None:
    """Run a step; its output goes to stderr (stdout is the command for the VM)."""
    done = subprocess.run([str(a) for a in argv], stdout=sys.stderr, check=False, **kwargs)  # type: ignore[call-overload]
    if done.returncode != 0:
        raise SystemExit(f"other-project: failed ({done.returncode}): {shlex.join(str(a) for a in argv)}")


def _clean_env() -> dict[str, str]:
    """This environment without what would reach the checkout's packages."""
    return {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "VIRTUAL_ENV"))}


def compiler_cache_env(base: Path = OUTSIDE) -> dict[str, str]:
    """The lamp's build through ccache where it is installed, as the checkout's own (CMakeLists.txt):
    by the variables CMake and ccache read (another project's CMakeLists needs nothing), paths under
    `base` (the lamp, its prefix) relative, so that a build in another folder hits the same objects.
    Empty without ccache."""
    if shutil.which("ccache") is None or os.environ.get("CMAKE_CXX_COMPILER_LAUNCHER"):
        return {}
    flags = " ".join(filter(None, [os.environ.get("CXXFLAGS"), f"-ffile-prefix-map={base}=."]))
    return {
        "CMAKE_CXX_COMPILER_LAUNCHER": "ccache",
        "CCACHE_BASEDIR": str(base),
        "CCACHE_NOHASHDIR": "1",
        "CXXFLAGS": flags,
    }


def fresh_venv(wheels: Path, venv: Path) -> Path:
    """A new venv with hilrig[pytest] from WHEELS, as a scenario author installs it: its
    dependencies from the package index at the versions requirements.lock pins (pip's cache
    has them after `make deps`, so nothing is downloaded twice); its python."""
    shutil.rmtree(venv, ignore_errors=True)
    _run([sys.executable, "-m", "venv", "--without-pip", venv])
    python = venv / "bin" / "python"
    # uv where tools/deps installed it (it links the cached wheels: 44 s of pip's unpacking on one
    # core became seconds), else pip; either resolves hilrig's own requirements from its wheel.
    uv = Path(sys.executable).parent / "uv"
    if uv.exists():
        # The wheel is always version 0.1.0: uv would take the one it cached from an earlier
        # checkout's build (a scaffold of that checkout's templates), not the one just built.
        installer = [uv, "pip", "install", "--quiet", "--native-tls", "--python", python,
                     "--refresh-package", "hilrig", "--reinstall-package", "hilrig"]  # fmt: skip
        if os.environ.get("PIP_FIND_LINKS"):  # pip reads it by itself, uv does not (tools/deps)
            installer += ["--find-links", os.environ["PIP_FIND_LINKS"]]
    else:
        installer = [sys.executable, "-m", "pip", "--python", python, "--disable-pip-version-check",
                     "install", "--quiet"]  # fmt: skip
    _run([*installer, "--find-links", wheels, "--constraint", REPO / "requirements.lock", "hilrig[pytest]"],
         env=_clean_env())  # fmt: skip
    return python


FIRMWARE_HEADER = "hilrig: firmware {firmware} (hil_firmware of pytest.ini)"
"""The line of pytest's header (hilrig's plugin) that says a project's own firmware runs."""

NEW_BOARD = "fan"
"""The board a new user makes with `hilrig new-board` (examples/fan: the scaffold and their edits)."""
USER_FILES = {"controller": ("firmware/components.hpp", "firmware/main.cpp"), "plant": ("fan_plant.py",),
              "scenario": ("test_fan.py",), "table": ("board.toml",)}  # fmt: skip
"""The files of examples/fan a new user edits after `hilrig new-board fan`, by what they hold."""
MAX_USER_LINES = 80
"""What the controller, the plant and the scenario may take of a new user's own lines."""


@dataclass(frozen=True)
class Project:
    """A project outside the checkout: its folder, its firmware, the trace `view --check` reads."""

    name: str
    folder: Path
    firmware: Path
    trace_of: str  # a scenario of it, whose trace.rrd the wheel's `hilrig view --check` reads
    approved: bool = True
    """Whether its approved traces are committed (approved/); the one as generated has none yet, so
    its run writes them, as a first run does (under CI a missing one fails)."""


def user_lines(scaffold: Path, edited: Path) -> dict[str, int]:
    """The lines of `edited` (examples/fan) that are not the scaffold's, by USER_FILES's groups;
    every other file of the scaffold must be in `edited` unchanged (else SystemExit)."""
    counted = {name for names in USER_FILES.values() for name in names}
    for path in sorted(p for p in scaffold.rglob("*") if p.is_file()):
        relative = str(path.relative_to(scaffold))
        if relative not in counted and path.read_text() != (edited / relative).read_text():
            raise SystemExit(f"new-board: {edited / relative} differs from the scaffold's: regenerate it")

    def new_lines(relative: str) -> int:
        old, new = (
            (scaffold / relative).read_text().splitlines(),
            (edited / relative).read_text().splitlines(),
        )
        return sum(1 for line in difflib.ndiff(old, new) if line.startswith("+ "))

    return {group: sum(map(new_lines, names)) for group, names in USER_FILES.items()}


def _build(project: Path, python: Path, prefix: Path) -> None:
    env = _clean_env() | compiler_cache_env()
    _run(
        ["cmake", "-S", project, "-B", project / "build", "-G", "Ninja", f"-DCMAKE_PREFIX_PATH={prefix}",
         f"-DHILFW_PYTHON={python}"],
        env=env,
    )  # fmt: skip
    _run(["cmake", "--build", project / "build"], env=env)


def prepare() -> tuple[Path, list[Project]]:
    """The native part: the wheel, the venv, the prefix; the lamp copied, a board scaffolded by
    the wheel's `hilrig new-board` as generated, and the fan a new user made of one (its own lines
    counted), each built against the prefix. Returns the venv's bin folder and the projects."""
    wheels = OUT / "dist"
    shutil.rmtree(wheels, ignore_errors=True)
    _run([sys.executable, REPO / "tools" / "dist.py", "--out", wheels], env=_clean_env())
    OUTSIDE.mkdir(parents=True, exist_ok=True)
    python = fresh_venv(wheels, OUTSIDE / "venv")
    prefix = OUTSIDE / "prefix"
    shutil.rmtree(prefix, ignore_errors=True)
    _run(["cmake", "--install", CMAKE_BUILD, "--component", "hilfw", "--prefix", prefix])
    for name in ("lamp", "sensor_board", NEW_BOARD, "scaffold"):
        shutil.rmtree(OUTSIDE / name, ignore_errors=True)
    lamp = OUTSIDE / "lamp"
    shutil.copytree(EXAMPLE, lamp, ignore=shutil.ignore_patterns("build", "__pycache__", "out"))
    # As a new user: `hilrig new-board` of the wheel, from the folder the project goes in.
    hilrig = python.parent / "hilrig"
    _run([hilrig, "new-board", "sensor_board"], cwd=OUTSIDE, env=_clean_env())
    _run(
        [hilrig, "new-board", NEW_BOARD, "--node-id", "0x21", "--dir", OUTSIDE / "scaffold"], env=_clean_env()
    )
    fan = OUTSIDE / NEW_BOARD
    shutil.copytree(
        REPO / "examples" / NEW_BOARD, fan, ignore=shutil.ignore_patterns("build", "__pycache__", "out")
    )
    counts = user_lines(OUTSIDE / "scaffold", fan)
    own = counts["controller"] + counts["plant"] + counts["scenario"]
    by_group = ", ".join(f"{group} {lines}" for group, lines in counts.items())
    print(
        f"new-board: the new user's own lines in {NEW_BOARD}: {by_group}; "
        f"controller + plant + scenario {own} (at most {MAX_USER_LINES})",
        file=sys.stderr,
    )
    if own > MAX_USER_LINES:
        raise SystemExit(f"new-board: {own} lines of a new user's own, more than {MAX_USER_LINES}")
    generated = OUTSIDE / "sensor_board"
    projects = [
        Project("lamp", lamp, lamp / "build" / "lamp-firmware", "test_the_light_follows_its_setpoint"),
        Project("sensor_board", generated, generated / "build" / "sensor_board-firmware",
                "test_the_input_follows_the_setpoint", approved=False),
        Project(NEW_BOARD, fan, fan / "build" / f"{NEW_BOARD}-firmware",
                "test_the_fan_holds_its_target_speed"),
    ]  # fmt: skip
    for project in projects:
        _build(project.folder, python, prefix)
    return python.parent, projects


def _junit_of(pytest_args: list[str], name: str) -> list[str]:
    """pytest's arguments for one project: a --junitxml=FILE.xml of its own (FILE-NAME.xml)."""
    return [
        f"{arg.removesuffix('.xml')}-{name}.xml" if arg.startswith("--junitxml=") else arg
        for arg in pytest_args
    ]


def run(bus_options: list[str], pytest_args: list[str]) -> int:
    """Each project's scenarios, then the wheel's `hilrig view --check` on one trace of each,
    in one boot of the wheel's `hilrig bus`; 0 when all passed, and each pytest header named the
    project's own firmware."""
    bin_dir, projects = prepare()
    env = _clean_env()
    checkout_uml = REPO / ".venv" / "bin" / "linux.uml"
    if checkout_uml.exists() and not env.get("HIL_UML_KERNEL"):
        env["HIL_UML_KERNEL"] = str(checkout_uml)  # the newer kernel tools/uml-kernel installed
    python, out = shlex.quote(str(bin_dir / "python")), '"${HIL_OUT_DIR:-out}"'
    steps = ["status=0"]
    for project in projects:
        first_run = [] if project.approved else ["--hil-approved=update"]
        pytest = shlex.join(
            [str(bin_dir / "python"), "-m", "pytest", *first_run, *_junit_of(pytest_args, project.name)]
        )
        trace = f"{out}/scenarios/{project.trace_of}/trace.rrd"
        steps.append(
            f"echo '== {project.name}'; cd {shlex.quote(str(project.folder))} && {pytest} "
            f"&& {python} -m hilrig view --check {trace} || status=1"
        )
    script = "; ".join([*steps, "exit $status"])
    argv = [str(bin_dir / "hilrig"), "bus", *bus_options, "--", "bash", "-c", script]
    print(
        f"other-project: {', '.join(p.name for p in projects)} through {bin_dir / 'hilrig'} bus",
        file=sys.stderr,
    )
    process = subprocess.Popen(argv, cwd=OUTSIDE, env=env, stdout=subprocess.PIPE, text=True)
    assert process.stdout is not None
    # A SIGTERM (run-tests interrupted) goes on to `hilrig bus`, which stops its guest; its
    # output and exit status are then read to the end as usual.
    signal.signal(signal.SIGTERM, lambda *_: process.terminate())
    seen: list[str] = []
    for line in process.stdout:
        sys.stdout.write(line)
        sys.stdout.flush()
        seen.append(line.rstrip("\n"))
    status = process.wait()
    if status == 130:  # interrupted: `hilrig bus` said so
        return status
    for project in projects:
        expected = FIRMWARE_HEADER.format(firmware=project.firmware.resolve())
        if expected not in seen:
            print(
                f"other-project: pytest's header lacks `{expected}`: not {project.name}'s firmware",
                file=sys.stderr,
            )
            status = status or 1
    return status


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("step", choices=["run"])
    parser.add_argument("--uml", action="store_true", help="force user-mode Linux (hilrig bus --uml)")
    arguments, pytest_args = parser.parse_known_args()  # the rest: pytest's
    return run(["--uml"] if arguments.uml else [], pytest_args)


if __name__ == "__main__":
    sys.exit(main())
