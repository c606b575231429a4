"""A scenario file for `hilrig sim --scenario` on the robot head with crane-fmu's oscillator as its
mount (docs/fmu.md): the rail closes at start-up and nods the head, then opens and lets it swing."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from hilrig.engine.rig import Rig


def scenario(rig: Rig) -> None:
    rig.run(seconds=0.1)
    rig.set("rail_enable", 0.0)
    rig.run(seconds=0.1)
