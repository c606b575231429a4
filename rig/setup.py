"""Build of the rig's C extensions (metadata: pyproject.toml): hilrig.physics._plant, the
joint's physics, and hilrig._rawcan, the batched frame I/O of the lockstep exchange.

The plant's arithmetic must stay bit-identical to the reference trajectories
(tests/data/physics_reference.json): no FMA contraction, no fast-math, libm's tanh/exp.
A missing compiler or CPython header fails here, by name, instead of deep in gcc's output.
"""

import os
import shutil
import sysconfig
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext


class BuildExtensionWithChecks(build_ext):
    def run(self) -> None:
        header = Path(sysconfig.get_paths()["include"]) / "Python.h"
        if not header.is_file():
            raise SystemExit(
                f"hilrig: cannot build its C extensions: {header} is missing "
                "(the CPython headers; on Debian: apt-get install python3-dev)"
            )
        compiler = (os.environ.get("CC") or sysconfig.get_config_var("CC") or "cc").split()[0]
        if shutil.which(compiler) is None:
            raise SystemExit(
                f"hilrig: cannot build its C extensions: C compiler {compiler!r} not found "
                "(on Debian: apt-get install gcc)"
            )
        super().run()


setup(
    ext_modules=[
        Extension(
            "hilrig.physics._plant",
            sources=["hilrig/physics/_plant.c"],
            extra_compile_args=["-std=c99", "-O2", "-ffp-contract=off", "-fno-fast-math", "-Wall", "-Wextra"],
            libraries=["m"],
        ),
        Extension(
            "hilrig._rawcan",
            sources=["hilrig/_rawcan.c"],
            extra_compile_args=["-std=c11", "-O2", "-Wall", "-Wextra"],
        ),
    ],
    cmdclass={"build_ext": BuildExtensionWithChecks},
)
