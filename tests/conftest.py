"""This repository's own part of the scenario fixtures: its board (pytest.ini's `hil_*` options
name its table, EDS, firmware and plant for hilrig's pytest plugin, which brings `make_scenario`,
`make_robot`, `private_bus`, `scenario_dir` and the `--hil-*` options), and a bare CANopen master
on the firmware (`node_under_test`) for the scenarios that talk to the node without a rig."""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import can
import canopen
import pytest

from boardproto.cia301 import SYNC_COB_ID, NmtState, heartbeat_cob_id
from hilrig.engine.lockstep import cycles_for
from hilrig.pytest_plugin import (
    BOOT_TIMEOUT_S,
    REALTIME_FIRMWARE_PERIOD_US,
    REALTIME_RIG_PERIOD_US,
    SCENARIO_SDO_TIMEOUT_S,
    run_hilrig,
)
from hilrig.session import baremetal
from hilrig.session.buslog import BusRecorder
from hilrig.session.firmware import DEFAULT_EXECUTABLE, Firmware, parse_stop_line
from hilrig.session.netns import PrivateBus
from hilrig.table import RigTable

REPO = Path(__file__).resolve().parent.parent
EDS = REPO / "build" / "protocol" / "board.eds"
TABLE = RigTable.load()
NODE_ID = TABLE.board.node.default_node_id
FULL_MAPPING_ON_THE_IDEAL_BUS = pytest.mark.ideal_bus(
    "the demo joint's full mapping at 1 kHz does not fit 1 Mbit/s: the real bus would drop its "
    "lowest-priority frames every cycle (hilrig bus-load; tests/test_bus_timing.py shows what it does)"
)
"""For a scenario whose point is not the mapping, run with the firmware's default (`full`) one:
on the table's bit rate its RPDO3 (control_mode) and TPDO4/TPDO7 never or rarely get on the bus."""
HEAD_MAPPING_ON_THE_IDEAL_BUS = pytest.mark.ideal_bus(
    "the head module's mapping at 1 kHz does not fit 1 Mbit/s (hilrig bus-load --table "
    "protocol/boards/head.toml)"
)


@dataclass
class NodeUnderTest:
    """The running firmware and a CANopen master talking to it on a private bus."""

    bus: can.BusABC
    network: canopen.Network
    node: canopen.RemoteNode
    firmware: Firmware
    bus_log: Path
    recorder: BusRecorder

    def wait_for(
        self,
        cob_id: int,
        timeout_s: float = 30.0,
        after_subscribing: Callable[[], object] | None = None,
        data: bytes | Callable[[bytes], bool] | None = None,
    ) -> can.Message:
        """The next frame with this COB-ID (and these data bytes, or data this predicate
        accepts, if given; bounded wait: a hang guard, not a timing check). `after_subscribing`
        sends the request that frame answers: only once we listen, so an answer faster than this
        thread cannot be missed."""
        got: list[can.Message] = []
        arrived = threading.Event()
        wanted = data

        def on_frame(can_id: int, data: bytearray, timestamp: float) -> None:
            if isinstance(wanted, bytes) and bytes(data) != wanted:
                return
            if callable(wanted) and not wanted(bytes(data)):
                return
            if not arrived.is_set():
                got.append(can.Message(arbitration_id=can_id, data=bytes(data), timestamp=timestamp))
                arrived.set()

        self.network.subscribe(cob_id, on_frame)
        try:
            if after_subscribing is not None:
                after_subscribing()
            if not arrived.wait(timeout_s):
                self.firmware.check()
                raise AssertionError(f"expected a frame with COB-ID {cob_id:#05x}, got none in {timeout_s} s")
            return got[0]
        finally:
            self.network.unsubscribe(cob_id, on_frame)

    def reset(self, state: str = "RESET") -> None:
        """python-canopen's reset (`node.nmt.state = "RESET"` or `"RESET COMMUNICATION"`), then
        `boot_syncs()`."""
        self.node.nmt.state = state
        self.boot_syncs()

    def boot_syncs(self, sync_cob_id: int = SYNC_COB_ID) -> None:
        """After an NMT reset, the SYNCs the node's boot time spans, on the COB-ID its 0x1005
        has after the reset (stored, or the default): the firmware runs lockstep, so it counts
        its boot time (the table's [node] boot_ms) in control cycles, one a SYNC, and this
        master is its SYNC producer. The boot-up comes with the last of them."""
        for _ in range(cycles_for(TABLE.board.node.boot_ms / 1e3, TABLE.board.node.period_us)):
            self.network.send_message(sync_cob_id, b"")


def start_node(
    private_bus: PrivateBus,
    scenario_dir: Path,
    params_file: Path | None = None,
    platform: str = baremetal.LINUX,
) -> NodeUnderTest:
    """The firmware on `platform` (hilrig.session.baremetal), booted, with a canopen master."""
    executable = baremetal.default_image(platform) if platform != baremetal.LINUX else DEFAULT_EXECUTABLE
    if not executable.exists() or not EDS.exists():
        pytest.fail(
            f"{executable} or {EDS} missing: run `make build` (and `make baremetal`) first", pytrace=False
        )
    bus_log = scenario_dir / "bus.log"
    recorder = BusRecorder(private_bus.open(), bus_log)
    bus = private_bus.open(receive_own_messages=True)
    network = canopen.Network(bus)
    network.connect()
    node = network.add_node(canopen.RemoteNode(NODE_ID, str(EDS)))
    # canopen's default (0.3 s) is shorter than its listener thread can take to hand an answer
    # over in a loaded VM: an answer on the bus within 1 ms was missed (test_recorder, fresh run).
    node.sdo.RESPONSE_TIMEOUT = SCENARIO_SDO_TIMEOUT_S
    booted = threading.Event()
    boot_up = bytes([NmtState.INITIALISING])
    network.subscribe(
        heartbeat_cob_id(NODE_ID), lambda can_id, data, ts: booted.set() if data[:1] == boot_up else None
    )
    firmware = Firmware(
        private_bus,
        node_id=NODE_ID,
        log_path=scenario_dir / "firmware.log",
        params_file=params_file,
        executable=executable,
        platform=platform,
    )
    firmware.start()
    if not booted.wait(BOOT_TIMEOUT_S):
        firmware.check()
        raise AssertionError(
            f"no boot-up message from node {NODE_ID:#x} within {BOOT_TIMEOUT_S} s; "
            f"firmware log: {firmware.log_path}"
        )
    return NodeUnderTest(
        bus=bus, network=network, node=node, firmware=firmware, bus_log=bus_log, recorder=recorder
    )


def stop_node(under_test: NodeUnderTest) -> int | None:
    code = under_test.firmware.stop()
    under_test.network.disconnect()
    under_test.bus.shutdown()
    under_test.recorder.close()
    return code


@pytest.fixture
def node_under_test(
    private_bus: PrivateBus, scenario_dir: Path, hil_firmware_platform: str
) -> Iterator[NodeUnderTest]:
    """The firmware in lockstep mode on a private bus, booted (pre-operational), with a
    canopen master; on teardown the firmware must stop cleanly on SIGTERM."""
    under_test = start_node(private_bus, scenario_dir, platform=hil_firmware_platform)
    try:
        yield under_test
    finally:
        code = stop_node(under_test)
    assert code == 0, (
        f"firmware did not exit cleanly on SIGTERM ({code}); log: {under_test.firmware.log_path}"
    )


@contextmanager
def fresh_network(private_bus: PrivateBus) -> Iterator[canopen.Network]:
    """A canopen network on a socket opened now, which hears only what is sent from now on.
    After a `hilrig` command has talked SDO to the node, a network that was listening has
    heard those answers too, and on a busy host its listener thread may hand one over late, as
    the answer to a request of its own (seen under user-mode Linux, the bus stage's lanes side
    by side: a read that got the command's abort)."""
    network = canopen.Network(private_bus.open())
    network.connect()
    try:
        yield network
    finally:
        network.disconnect()


@contextmanager
def own_master(private_bus: PrivateBus) -> Iterator[canopen.RemoteNode]:
    """A canopen master of the node on a `fresh_network`."""
    with fresh_network(private_bus) as network:
        node = network.add_node(canopen.RemoteNode(NODE_ID, str(EDS)))
        node.sdo.RESPONSE_TIMEOUT = SCENARIO_SDO_TIMEOUT_S
        yield node


def stop_summary(firmware: Firmware) -> dict[str, int]:
    """The counters of the firmware's stop line (printed on SIGTERM), by name:
    {"cycles": 812, "overruns": 0, "frames received": 4100, "ignored": 3, "malformed": 0, ...}."""
    parsed = parse_stop_line(firmware.log_path.read_text(errors="replace"))
    assert parsed is not None, f"no stop summary in {firmware.log_path}:\n{firmware.log_tail()}"
    return parsed[1]


__all__ = [
    "BOOT_TIMEOUT_S",
    "EDS",
    "NODE_ID",
    "REALTIME_FIRMWARE_PERIOD_US",
    "REALTIME_RIG_PERIOD_US",
    "REPO",
    "SCENARIO_SDO_TIMEOUT_S",
    "TABLE",
    "NodeUnderTest",
    "fresh_network",
    "own_master",
    "run_hilrig",
    "start_node",
    "stop_node",
    "stop_summary",
]
