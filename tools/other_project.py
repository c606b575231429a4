"""examples/other-project from outside the checkout, as another project would use hil-rig:
hilrig's wheel (`make dist`) installed into a fresh venv, hil-rig's firmware package installed
from the CMake build (`cmake --install build --component hilfw`), the lamp's firmware built
against that prefix with the wheel's generator, and the lamp's scenarios run by the wheel's pytest
plugin with the example as the working directory and no PYTHONPATH. `tools/run-tests` runs the
native part and the scenarios in its bus stage's VM:

    .venv/bin/python tools/other_project.py prepare [PYTEST_ARGS...]  # prints the command for the VM

Everything goes under build/other-project/ (the wheel, the venv, the prefix) and
examples/other-project/build/ (the lamp's build tree, which its pytest.ini names). The venv is
an installer's own install of the wheel and pytest (uv's, as tools/deps uses it, else pip's),
nothing of the checkout's venv in it.
"""

from __future__ import annotations

import argparse
import os
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
EXAMPLE = REPO / "examples" / "other-project"
OUT = REPO / "build" / "other-project"
CMAKE_BUILD = Path(os.environ.get("HILFW_BUILD", REPO / "build"))
"""The configured CMake build tree whose install rules hold the firmware package: `make build`'s,
or $HILFW_BUILD (a tree configured by hand, e.g. a worktree whose build/ links another's)."""


LAMP_SCENARIO = "test_the_light_follows_its_setpoint"
"""The lamp's scenario (examples/other-project/test_lamp.py) whose trace `hilrig view --check` reads."""


def _run(argv: list[str | Path], **kwargs: object) -> None:
    """Run a step; its output goes to stderr (stdout is the command for the VM)."""
    done = subprocess.run([str(a) for a in argv], stdout=sys.stderr, check=False, **kwargs)  # type: ignore[call-overload]
    if done.returncode != 0:
        raise SystemExit(f"other-project: failed ({done.returncode}): {shlex.join(str(a) for a in argv)}")


def _clean_env() -> dict[str, str]:
    """This environment without what would reach the checkout's packages."""
    return {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "VIRTUAL_ENV"))}


def compiler_cache_env() -> dict[str, str]:
    """The lamp's build through ccache where it is installed, as the checkout's own (CMakeLists.txt):
    by the variables CMake and ccache read (another project's CMakeLists needs nothing), paths under
    the checkout relative, so that another clone's build hits the same objects. Empty without ccache."""
    if shutil.which("ccache") is None or os.environ.get("CMAKE_CXX_COMPILER_LAUNCHER"):
        return {}
    flags = " ".join(filter(None, [os.environ.get("CXXFLAGS"), f"-ffile-prefix-map={REPO}=."]))
    return {
        "CMAKE_CXX_COMPILER_LAUNCHER": "ccache",
        "CCACHE_BASEDIR": str(REPO),
        "CCACHE_NOHASHDIR": "1",
        "CXXFLAGS": flags,
    }


def fresh_venv(wheels: Path, venv: Path) -> Path:
    """A new venv with hilrig from WHEELS and pytest, as another project installs them: its
    dependencies from the package index at the versions requirements.lock pins (pip's cache
    has them after `make deps`, so nothing is downloaded twice); its python."""
    shutil.rmtree(venv, ignore_errors=True)
    _run([sys.executable, "-m", "venv", "--without-pip", venv])
    python = venv / "bin" / "python"
    # uv where tools/deps installed it (it links the cached wheels: 44 s of pip's unpacking on one
    # core became seconds), else pip; either resolves hilrig's own requirements from its wheel.
    uv = Path(sys.executable).parent / "uv"
    if uv.exists():
        installer = [uv, "pip", "install", "--quiet", "--native-tls", "--python", python]
        if os.environ.get("PIP_FIND_LINKS"):  # pip reads it by itself, uv does not (tools/deps)
            installer += ["--find-links", os.environ["PIP_FIND_LINKS"]]
    else:
        installer = [sys.executable, "-m", "pip", "--python", python, "--disable-pip-version-check",
                     "install", "--quiet"]  # fmt: skip
    _run([*installer, "--find-links", wheels, "--constraint", REPO / "requirements.lock", "hilrig", "pytest"],
         env=_clean_env())  # fmt: skip
    return python


def prepare(pytest_args: list[str]) -> str:
    """The native part; returns the shell command that runs the lamp's scenarios (in the VM), in
    a subshell, with `pytest_args` after pytest's own."""
    wheels = OUT / "dist"
    shutil.rmtree(wheels, ignore_errors=True)
    _run([sys.executable, REPO / "tools" / "dist.py", "--out", wheels], env=_clean_env())
    python = fresh_venv(wheels, OUT / "venv")
    prefix = OUT / "prefix"
    shutil.rmtree(prefix, ignore_errors=True)
    _run(["cmake", "--install", CMAKE_BUILD, "--component", "hilfw", "--prefix", prefix])
    lamp_build = EXAMPLE / "build"
    shutil.rmtree(lamp_build, ignore_errors=True)
    env = _clean_env() | compiler_cache_env()
    _run(
        ["cmake", "-S", EXAMPLE, "-B", lamp_build, "-G", "Ninja", f"-DCMAKE_PREFIX_PATH={prefix}",
         f"-DHILFW_PYTHON={python}"],
        env=env,
    )  # fmt: skip
    _run(["cmake", "--build", lamp_build], env=env)
    # Its own hilrig and firmware: not this checkout's PYTHONPATH, nor its $HIL_FIRMWARE (which
    # tools/with-vcan sets under user-mode Linux, and which the plugin would take over the lamp's).
    pytest = shlex.join(
        ["env", "-u", "PYTHONPATH", "-u", "HIL_FIRMWARE", str(python), "-m", "pytest", "-q", *pytest_args]
    )
    # The wheel's `hilrig view --check` on the lamp scenario's trace: it opens with the dashboard
    # generated from the lamp's table and plant, every series it names with data.
    check = shlex.join(["env", "-u", "PYTHONPATH", str(python), "-m", "hilrig", "view", "--check"])
    trace = f'"${{HIL_OUT_DIR:-out}}/scenarios/{LAMP_SCENARIO}/trace.rrd"'
    return f"(cd {shlex.quote(str(EXAMPLE))} && {pytest} && {check} {trace})"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("step", choices=["prepare"])
    parser.add_argument("pytest_args", nargs=argparse.REMAINDER, help="more arguments for pytest")
    arguments = parser.parse_args()
    print(prepare(arguments.pytest_args))
    return 0


if __name__ == "__main__":
    sys.exit(main())
