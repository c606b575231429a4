"""hilrig's labgrid plugin without a bus: an env YAML importing it makes a target whose CANDriver
gives the session its board interface (the bus-level run through labgrid: tests/test_labgrid.py)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from labgrid import Environment
from labgrid.target import Target

from hilrig.session.builder import BoardInterface


def _target(tmp_path: Path, resources: str, driver: str = "{}") -> Target:
    env = tmp_path / "env.yaml"
    env.write_text(
        f"imports: [hilrig.lab]\ntargets:\n  main:\n    resources:\n{resources}"
        f"    drivers:\n      CANDriver: {driver}\n"
    )
    return Environment(str(env)).get_target("main")


def test_a_local_port_is_the_bus_of_the_board(tmp_path: Path) -> None:
    target = _target(tmp_path, "      CANPort: {ifname: can1, bitrate: 250000}\n")
    driver = target.get_driver("CANDriver")
    assert driver.board_interface() == BoardInterface("socketcan", "can1", 250000)


def test_a_port_on_another_host_asks_for_a_bridge(tmp_path: Path) -> None:
    remote = "      NetworkCANPort: {host: farm-7.example, ifname: can0}\n"
    with pytest.raises(ValueError, match=re.escape("on host farm-7.example, not this one: bridge it here")):
        _target(tmp_path, remote).get_driver("CANDriver").board_interface()
    bridged = _target(tmp_path, remote, "{channel: vcan-farm7}").get_driver("CANDriver")
    assert bridged.board_interface() == BoardInterface("socketcan", "vcan-farm7", None)
