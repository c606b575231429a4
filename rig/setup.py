"""Build of the rig (metadata: pyproject.toml): its packages, its C extensions and, in a wheel,
the board's files.

C extensions: hilrig.wire._wire, the per-cycle PDO exchange on a raw CAN socket (hilrig.wire.transport's
fast path), and hilrig.plants._plant, the joint's physics, both on the limited API (abi3: one
wheel for CPython 3.11 and later). Its arithmetic must stay bit-identical to
the reference trajectories (tests/data/physics_reference.json): no FMA contraction, no fast-math,
libm's tanh/exp. A missing compiler or CPython header fails here, by name, instead of deep in
gcc's output.

Two source trees build here:
- the checkout's rig/ (the project's .venv installs it editable, tools/deps): hilrig, and the
  checkout's dashboards/ mapped as the top-level `dashboards` it imports there; boardproto is
  the checkout's protocol/ (installed editable beside it). A wheel is never built from it.
- the self-contained tree `make dist` stages and packs as the sdist (tools/dist.py): the table's
  generators under hilrig.boardproto, the dashboards under hilrig.dashboards (their imports
  pointed there), board.toml beside this file. Its wheel installs `hilrig` alone and requires
  nothing of ours: no name another party could register on the package index.

The board's files (wheel only): hilrig/data/ gets board.toml and the EDS and DBC that
hilrig.boardproto generates from it, as CMake generates build/protocol/ (hilrig.resources reads
them when hilrig is installed).
"""

import os
import shutil
import sys
import sysconfig
from pathlib import Path

from setuptools import Extension, find_packages, setup
from setuptools.command.build_ext import build_ext
from setuptools.command.build_py import build_py

SOURCE = Path(__file__).resolve().parent
SELF_CONTAINED = (SOURCE / "hilrig" / "boardproto" / "__init__.py").is_file()
"""The tree tools/dist.py staged (and its sdist), not the checkout's rig/."""
BOARD_TABLE = SOURCE / "board.toml"
PACKAGED_BOARD_FILES = Path("hilrig") / "data"


class BuildExtensionWithChecks(build_ext):
    def run(self) -> None:
        header = Path(sysconfig.get_paths()["include"]) / "Python.h"
        if not header.is_file():
            raise SystemExit(
                f"hilrig: cannot build its C extensions (hilrig.wire._wire, hilrig.plants._plant): {header} "
                "is missing (the CPython headers; on Debian: apt-get install python3-dev)"
            )
        compiler = (os.environ.get("CC") or sysconfig.get_config_var("CC") or "cc").split()[0]
        if shutil.which(compiler) is None:
            raise SystemExit(
                f"hilrig: cannot build its C extensions (hilrig.wire._wire, hilrig.plants._plant): "
                f"C compiler {compiler!r} not found (on Debian: apt-get install gcc)"
            )
        super().run()


class BuildPyWithBoardFiles(build_py):
    def run(self) -> None:
        super().run()
        if not getattr(self, "editable_mode", False):  # editable: hilrig reads the checkout's files
            write_board_files(Path(self.build_lib) / PACKAGED_BOARD_FILES)


def write_board_files(out_dir: Path) -> None:
    if not SELF_CONTAINED or not BOARD_TABLE.is_file():
        raise SystemExit(
            "hilrig: a wheel is built from the tree `make dist` stages (tools/dist.py: the table's "
            "generators and the dashboards under hilrig), or from its sdist; not from rig/ itself"
        )
    sys.path.insert(0, str(SOURCE))  # this tree's generator, as CMake runs the checkout's
    try:
        from hilrig.boardproto import load_table
        from hilrig.boardproto.dbc import generate_dbc
        from hilrig.boardproto.eds import generate_eds
    except ImportError as error:
        raise SystemExit(
            f"hilrig: cannot generate the board's EDS and DBC: {error} (build with canopen and "
            "cantools installed: `make dist`, or pip's default isolated build)"
        ) from None
    table = load_table(BOARD_TABLE)
    out_dir.mkdir(parents=True, exist_ok=True)
    shutil.copy2(BOARD_TABLE, out_dir / "board.toml")
    (out_dir / "board.eds").write_bytes(generate_eds(table).encode())  # as boardproto writes them
    (out_dir / "board.dbc").write_bytes(generate_dbc(table).encode())


setup(
    packages=find_packages(include=["hilrig", "hilrig.*"]) + ([] if SELF_CONTAINED else ["dashboards"]),
    # The new-board template (hilrig.apps.scaffold): files, not modules.
    package_data={"hilrig.apps.scaffold": ["template/*", "template/*/*", "template/*/*/*"]},
    package_dir={"": "."} if SELF_CONTAINED else {"": ".", "dashboards": "../dashboards"},
    ext_modules=[
        Extension(
            "hilrig.plants._plant",
            sources=["hilrig/plants/_plant.c"],
            depends=["hilrig/plants/_joint_core.h"],  # the physics it shares with the joint's FMU
            extra_compile_args=["-std=c99", "-O2", "-ffp-contract=off", "-fno-fast-math", "-Wall", "-Wextra"],
            libraries=["m"],
            py_limited_api=SELF_CONTAINED,
        ),
        Extension(
            "hilrig.wire._wire",
            sources=["hilrig/wire/_wire.c"],
            extra_compile_args=["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror"],
            py_limited_api=SELF_CONTAINED,
        ),
    ],
    cmdclass={"build_ext": BuildExtensionWithChecks, "build_py": BuildPyWithBoardFiles},
    # The extensions use the limited API of 3.11 (Py_LIMITED_API in their sources): the wheel
    # is abi3, for CPython 3.11 and later. The checkout's editable build keeps the version's own
    # file name, so an earlier in-place build is replaced, never shadowed.
    options={"bdist_wheel": {"py_limited_api": "cp311"}} if SELF_CONTAINED else {},
)
