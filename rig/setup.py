"""Build of the rig (metadata: pyproject.toml): its packages, its C extensions and, in a wheel,
the board's files.

C extensions: hilrig.wire._wire, the per-cycle PDO exchange on a raw CAN socket (hilrig.wire.transport's
fast path), and hilrig.plants._plant, the joint's physics. Its arithmetic must stay bit-identical to
the reference trajectories (tests/data/physics_reference.json): no FMA contraction, no fast-math,
libm's tanh/exp. A missing compiler or CPython header fails here, by name, instead of deep in
gcc's output.

Packages: hilrig, and dashboards from the repository's root (hilrig.observe loads
its blueprints, so the two ship together). The editable install maps both onto the checkout.

The board's files (wheel only): hilrig/data/ gets protocol/board.toml and the EDS and DBC that the
checkout's boardproto generates from it, as CMake generates build/protocol/ (hilrig.resources reads
them when hilrig is installed). So a wheel is built from a checkout (`make dist`, or `pip wheel rig`),
never from an sdist alone.
"""

import os
import shutil
import sys
import sysconfig
from pathlib import Path

from setuptools import Extension, find_packages, setup
from setuptools.command.build_ext import build_ext
from setuptools.command.build_py import build_py

CHECKOUT = Path(__file__).resolve().parent.parent
PROTOCOL = CHECKOUT / "protocol"
BOARD_TABLE = PROTOCOL / "board.toml"
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
    if not BOARD_TABLE.is_file():
        raise SystemExit(
            f"hilrig: the wheel is built from a checkout: {BOARD_TABLE} is missing (run `make dist` "
            "in the repository)"
        )
    sys.path.insert(0, str(PROTOCOL))  # this checkout's generator, as CMake runs it (PYTHONPATH)
    try:
        from boardproto import load_table
        from boardproto.dbc import generate_dbc
        from boardproto.eds import generate_eds
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
    packages=[*find_packages(include=["hilrig", "hilrig.*"]), "dashboards"],
    package_dir={"": ".", "dashboards": "../dashboards"},
    ext_modules=[
        Extension(
            "hilrig.plants._plant",
            sources=["hilrig/plants/_plant.c"],
            extra_compile_args=["-std=c99", "-O2", "-ffp-contract=off", "-fno-fast-math", "-Wall", "-Wextra"],
            libraries=["m"],
        ),
        Extension(
            "hilrig.wire._wire",
            sources=["hilrig/wire/_wire.c"],
            extra_compile_args=["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror"],
        ),
    ],
    cmdclass={"build_ext": BuildExtensionWithChecks, "build_py": BuildPyWithBoardFiles},
)
