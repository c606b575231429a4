"""A parameter set moves from one board to the next as a DCF: `hilrig params save` on a tuned
board, `hilrig params load` on a fresh one (another node id); the second then holds every stored
object with the DCF's value (COB-IDs relative to each node's id), and keeps the tuning after a
restart."""

from __future__ import annotations

import subprocess
from collections.abc import Iterator
from contextlib import ExitStack
from pathlib import Path

import canopen
import pytest
from canopen.objectdictionary import ODVariable
from conftest import BOOT_TIMEOUT_S, EDS, SCENARIO_SDO_TIMEOUT_S, fresh_network, run_hilrig

from boardproto.cia301 import NODE_ID_MASK
from boardproto.table import PDO_NOT_VALID
from hilrig.session.firmware import Firmware
from hilrig.session.netns import PrivateBus
from hilrig.table import RigTable
from hilrig.wire.dcf import read_dcf, stored_objects
from hilrig.wire.lss import BootUpWatch

pytestmark = pytest.mark.bus

TABLE = RigTable.load()
TUNED, FRESH = 1, 2


@pytest.fixture
def network(private_bus: PrivateBus) -> Iterator[canopen.Network]:
    with fresh_network(private_bus) as network:
        yield network


def hilrig(private_bus: PrivateBus, *argv: str) -> subprocess.CompletedProcess[str]:
    return run_hilrig(private_bus, *argv, "--sdo-timeout", str(SCENARIO_SDO_TIMEOUT_S))


def normalized(var: ODVariable, value: object, node_id: int) -> object:
    """A COB-ID that follows the node id as its offset from it; any other value as it is."""
    if getattr(var, "relative", False) and isinstance(value, int) and value & NODE_ID_MASK == node_id:
        return value - node_id
    return value


def stored_values(network: canopen.Network, node_id: int) -> dict[tuple[int, int], object]:
    """Every stored object of the node, read over SDO (COB-IDs `normalized`)."""
    remote = canopen.RemoteNode(node_id, canopen.import_od(str(EDS), node_id))
    remote.sdo.RESPONSE_TIMEOUT = SCENARIO_SDO_TIMEOUT_S
    network.add_node(remote)
    values = {}
    try:
        for var in stored_objects(remote.object_dictionary, TABLE):
            obj = remote.object_dictionary[var.index]
            sdo = remote.sdo[var.index] if obj is var else remote.sdo[var.index][var.subindex]
            values[var.index, var.subindex] = normalized(var, sdo.raw, node_id)
    finally:
        del network[node_id]
    return values


def dcf_values(path: Path, node_id: int) -> dict[tuple[int, int], object]:
    """Every stored object's ParameterValue in the DCF (COB-IDs `normalized`)."""
    od = read_dcf(path, node_id)
    return {(v.index, v.subindex): normalized(v, v.value, node_id) for v in stored_objects(od, TABLE)}


@pytest.mark.requirement("STORE_02")
def test_a_dcf_saved_from_one_board_and_loaded_into_another_equals_it(
    private_bus: PrivateBus, scenario_dir: Path, network: canopen.Network
) -> None:
    boards = {
        node_id: Firmware(
            private_bus,
            node_id=node_id,
            log_path=scenario_dir / f"firmware-{node_id}.log",
            params_file=scenario_dir / f"params-{node_id}.bin",
        )
        for node_id in (TUNED, FRESH)
    }
    with ExitStack() as stack:
        for node_id, board in boards.items():
            (scenario_dir / f"params-{node_id}.bin").unlink(missing_ok=True)
            with BootUpWatch(network, node_id) as booted:
                stack.enter_context(board)
                booted.wait(BOOT_TIMEOUT_S)
        tuned = canopen.RemoteNode(TUNED, canopen.import_od(str(EDS), TUNED))
        tuned.sdo.RESPONSE_TIMEOUT = SCENARIO_SDO_TIMEOUT_S
        network.add_node(tuned)
        tuned.sdo[TABLE.field("velocity_kp").index].raw = 0.1875
        tuned.sdo[0x1017].raw = 77
        tpdo1_cob_id = tuned.sdo[0x1800][1].raw  # TPDO1 keeps only its first mapped object:
        tuned.sdo[0x1800][1].raw = tpdo1_cob_id | PDO_NOT_VALID  # CiA 301: invalid first,
        tuned.sdo[0x1A00][0].raw = 1  # the mapping,
        tuned.sdo[0x1800][1].raw = tpdo1_cob_id  # valid again
        kp = TABLE.field("velocity_kp").index
        fresh = canopen.RemoteNode(FRESH, canopen.import_od(str(EDS), FRESH))
        fresh.sdo.RESPONSE_TIMEOUT = SCENARIO_SDO_TIMEOUT_S
        network.add_node(fresh)
        assert fresh.sdo[kp].raw != tuned.sdo[kp].raw, "the fresh board starts untuned"

        dcf = scenario_dir / "tuned.dcf"
        saved = hilrig(private_bus, "params", "save", str(dcf), "-n", str(TUNED))
        assert saved.returncode == 0, saved.stderr
        tuned_values = dcf_values(dcf, TUNED)
        assert None not in tuned_values.values(), "every stored object has its value in the DCF"
        assert (tuned_values[kp, 0], tuned_values[0x1017, 0], tuned_values[0x1A00, 0]) == (0.1875, 77, 1)

        loaded = hilrig(private_bus, "params", "load", str(dcf), "-n", str(FRESH))
        assert loaded.returncode == 0, loaded.stderr
        assert "stored (0x1010)" in loaded.stdout
        # Read back on a new socket (`fresh_network`): `network` heard the commands' answers too.
        del network[TUNED], network[FRESH]
        network = stack.enter_context(fresh_network(private_bus))
        assert stored_values(network, FRESH) == tuned_values

        with BootUpWatch(network, FRESH) as booted:
            boards[FRESH].restart()
            booted.wait(BOOT_TIMEOUT_S)
        network.add_node(fresh)
        after_restart = (fresh.sdo[kp].raw, fresh.sdo[0x1017].raw, fresh.sdo[0x1A00][0].raw)
        assert after_restart == (0.1875, 77, 1), "stored with 0x1010: the same after a restart"
