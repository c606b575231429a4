"""New boards get their node ids over LSS (CiA 305): a modular robot's modules, none with an id,
numbered in chain order by `hilrig lss number --chain` and stored; and python-canopen's own LSS
master (`network.lss`) giving a board its id, as a user of that library would."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import ExitStack
from pathlib import Path

import canopen
import pytest
from conftest import BOOT_TIMEOUT_S, REPO, SCENARIO_SDO_TIMEOUT_S, run_hilrig

from boardproto import load_table
from boardproto.cia305 import NODE_ID_UNCONFIGURED
from hilrig.session.chain import UnconfiguredChain
from hilrig.session.netns import PrivateBus
from hilrig.wire.lss import BootUpWatch, LssAddress, LssCommissioner, read_identity

pytestmark = pytest.mark.bus

NODE = load_table(REPO / "protocol" / "board.toml").node
# LSS answers "no" by silence: how long a question waits. On a real bus an answer takes a
# millisecond; in the emulated VM four ASan firmware processes and the rig share two CPUs, and an
# answer 0.5 s late was seen.
LSS_TIMEOUT_S = 2.0
# Serial numbers out of chain order (fastscan alone would number them 4, 1, 3, 2), with one 1 bit
# each: every 1 bit costs fastscan a silent LSS_TIMEOUT_S.
CHAIN_SERIALS = (0x08, 0x01, 0x04, 0x02)


@pytest.fixture
def network(private_bus: PrivateBus) -> Iterator[canopen.Network]:
    bus = private_bus.open()
    network = canopen.Network(bus)
    network.connect()
    try:
        yield network
    finally:
        network.disconnect()


@pytest.mark.requirement("LSS_01")
def test_four_modules_are_numbered_in_chain_order_and_keep_their_ids(
    private_bus: PrivateBus, scenario_dir: Path, network: canopen.Network
) -> None:
    with UnconfiguredChain(private_bus, scenario_dir, CHAIN_SERIALS) as chain:
        lss = LssCommissioner(network, timeout_s=LSS_TIMEOUT_S)
        assert lss.identify_non_configured()
        numbered = run_hilrig(
            private_bus, "lss", "number", "--chain", "--count", "4",
            "--timeout", str(LSS_TIMEOUT_S), "--boot-timeout", "30",
        )  # fmt: skip
        assert numbered.returncode == 0, numbered.stderr
        rows = [line.split()[:3] for line in numbered.stdout.splitlines()[1:]]
        assert rows == [[f"0x{k:02X}", f"0x{serial:08X}", "yes"] for k, serial in enumerate(CHAIN_SERIALS, 1)]
        assert "4 boards numbered 0x01..0x04 in chain order" in numbered.stderr
        assert not lss.any_unconfigured()

        # Power-cycle the whole robot: every module boots with the id it stored.
        with ExitStack() as watching:
            watches = [watching.enter_context(BootUpWatch(network, m.position)) for m in chain.modules]
            for module in chain.modules:
                module.firmware.restart()
            for watch in watches:
                watch.wait(BOOT_TIMEOUT_S)
        for module in chain.modules:
            identity = read_identity(network, module.position, SCENARIO_SDO_TIMEOUT_S)
            assert identity == LssAddress(
                NODE.vendor_id, NODE.product_code, NODE.revision, module.serial_number
            )
        assert not lss.any_unconfigured()
        for module in chain.modules:  # the chain output switched once, when its id came
            log = module.firmware.log_path.read_text(errors="replace")
            assert log.count("configured over LSS") == 1, f"{module.firmware.log_path}: {log[-2000:]}"


@pytest.mark.requirement("LSS_01")
def test_python_canopens_lss_master_gives_a_board_its_id(
    private_bus: PrivateBus, scenario_dir: Path, network: canopen.Network
) -> None:
    master = network.lss
    master.RESPONSE_TIMEOUT = SCENARIO_SDO_TIMEOUT_S
    with UnconfiguredChain(private_bus, scenario_dir, (0x2A,)):
        master.send_switch_state_global(master.CONFIGURATION_STATE)
        assert master.inquire_node_id() == NODE_ID_UNCONFIGURED
        assert master.inquire_lss_address(canopen.lss.CS_INQUIRE_SERIAL_NUMBER) == 0x2A
        assert master.inquire_lss_address(canopen.lss.CS_INQUIRE_VENDOR_ID) == NODE.vendor_id
        master.configure_node_id(0x21)
        master.store_configuration()
        with BootUpWatch(network, 0x21) as booted:
            master.send_switch_state_global(master.WAITING_STATE)
            booted.wait(BOOT_TIMEOUT_S)
        assert read_identity(network, 0x21, SCENARIO_SDO_TIMEOUT_S).serial_number == 0x2A
