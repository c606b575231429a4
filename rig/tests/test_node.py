"""Name checks against board.toml and the SDO abort wording, without a bus."""

from __future__ import annotations

import pytest

from boardproto.cia301 import STANDARD_ID_MASK, FunctionCode, NmtCommand, NmtState, SdoAbortCode, cob_id
from hilrig.errors import FieldNameError
from hilrig.table import RigTable
from hilrig.wire.node import explain_abort
from hilrig.wire.transport import PdoDirection, PdoLayout

TPDO2_ID = cob_id(FunctionCode.TPDO2, 0x10)  # of node 0x10


@pytest.fixture(scope="module")
def table() -> RigTable:
    return RigTable.load()


@pytest.mark.parametrize(
    ("code", "name", "expected"),
    [
        (SdoAbortCode.VALUE_TOO_HIGH, "velocity_kp", "0x06090031 value too high (max 10.0)"),
        (SdoAbortCode.VALUE_TOO_LOW, "velocity_kp", "0x06090032 value too low (min 0.0)"),
        (SdoAbortCode.VALUE_RANGE_EXCEEDED, "velocity_kp", "0x06090030 value out of range (range 0.0..10.0)"),
        (SdoAbortCode.READ_ONLY, "motor_velocity", "0x06010002 object is read-only over the bus"),
        (SdoAbortCode.OBJECT_DOES_NOT_EXIST, None, "0x06020000 no such object in the node's dictionary"),
        (
            SdoAbortCode.DEVICE_STATE,
            None,
            "0x08000022 not possible in the node's present state (e.g. PDO change while operational)",
        ),
        (0x12345678, None, "0x12345678 unknown abort code"),
    ],
)
def test_abort_codes_are_explained_in_words(
    table: RigTable, code: int, name: str | None, expected: str
) -> None:
    assert explain_abort(code, table.entry(name) if name else None) == expected


def test_every_abort_code_is_explained_in_the_words_of_boardproto() -> None:
    """The firmware's codes are generated from the same enum (board/cia301.hpp), so every code
    it can send is one of these."""
    for code in SdoAbortCode:
        assert explain_abort(code) == f"0x{code:08X} {code.text}"


def test_unknown_field_lists_close_matches(table: RigTable) -> None:
    with pytest.raises(FieldNameError) as info:
        table.entry("velocity_setpont")
    assert str(info.value) == (
        "no board field or HIL I/O object named 'velocity_setpont'; "
        "did you mean 'velocity_setpoint' or 'velocity_kp' or 'velocity_ki'?"
    )


def test_name_without_close_match_says_so_plainly(table: RigTable) -> None:
    with pytest.raises(FieldNameError, match=r"^no board field or HIL I/O object named 'xyz'$"):
        table.check(["motor_duty", "xyz"])


def test_table_is_the_generated_one_not_a_copy(table: RigTable) -> None:
    assert table.board.source.name == "board.toml"
    assert table.entry("motor_velocity").index == 0x2100
    assert table.is_hil_input("thermistor_adc")
    assert not table.is_hil_input("motor_duty")
    assert table.is_bus_writable("velocity_kp") and not table.is_bus_writable("motor_velocity")


@pytest.mark.parametrize(
    ("transmission_type", "due_syncs"),
    [
        (1, [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12]),
        (10, [10]),
        (4, [4, 8, 12]),
        (0, []),  # acyclic: only when changed, never due
        (255, []),  # event driven
    ],
)
def test_tpdo_due_at_every_nth_sync_since_operational(transmission_type: int, due_syncs: list[int]) -> None:
    pdo = PdoLayout(PdoDirection.TPDO, 2, TPDO2_ID, True, transmission_type, ("a", "b"))
    assert [n for n in range(1, 13) if pdo.due_at_sync(n)] == due_syncs
    assert pdo.label == "TPDO2 (0x290)"


def test_nmt_commands_end_in_the_states_cia301_defines() -> None:
    assert NmtCommand.START.resulting_state is NmtState.OPERATIONAL
    assert NmtCommand.STOP.resulting_state is NmtState.STOPPED
    assert NmtCommand.RESET_NODE.resulting_state is NmtState.PRE_OPERATIONAL
    assert NmtState.PRE_OPERATIONAL == 0x7F


def test_a_node_narrowed_to_answers_hears_its_sdo_answers_and_heartbeats_only(table: RigTable) -> None:
    import threading

    import can

    from boardproto.cia301 import heartbeat_cob_id, sdo_response_cob_id
    from hilrig.wire.node import BoardNode

    node_id = 0x10
    ours = can.Bus(interface="virtual", channel="narrowed", receive_own_messages=False)
    board = can.Bus(interface="virtual", channel="narrowed")
    node = BoardNode(ours, node_id, None, table)
    heard: list[int] = []
    last = threading.Event()
    wanted = {sdo_response_cob_id(node_id), heartbeat_cob_id(node_id)}
    tpdo1 = cob_id(FunctionCode.TPDO1, node_id)
    for cob in (tpdo1, *wanted):
        node.network.subscribe(cob, lambda can_id, data, ts: (heard.append(can_id), last.set()))
    try:
        node.receive_only_answers()
        for cob in (tpdo1, sdo_response_cob_id(node_id), tpdo1, heartbeat_cob_id(node_id)):
            board.send(
                can.Message(
                    arbitration_id=cob,
                    data=bytes(8 if cob != heartbeat_cob_id(node_id) else 1),
                    is_extended_id=False,
                )
            )
        deadline = 50  # x 0.1 s: a hang guard, the frames are in memory
        while len(heard) < 2 and deadline:
            last.wait(0.1)
            deadline -= 1
        assert heard == [sdo_response_cob_id(node_id), heartbeat_cob_id(node_id)]
    finally:
        node.close()
        ours.shutdown()
        board.shutdown()


@pytest.mark.parametrize("node_id", [1, 9, 16, 63, 127])
def test_a_nodes_dictionary_is_the_one_canopen_reads_from_the_eds_for_that_node(node_id: int) -> None:
    # Parsed once, copied per node (a robot has a node per module): every entry as canopen's own
    # import for that node id, the COB-IDs relative to it ($NODEID) included.
    import canopen

    from hilrig.engine.rig import DEFAULT_EDS_PATH
    from hilrig.wire.node import node_dictionary

    def entries(od: canopen.ObjectDictionary) -> dict[tuple[int, int], tuple[object, ...]]:
        return {
            (v.index, v.subindex): (v.name, v.data_type, v.default, v.value, v.relative, v.min, v.max)
            for entry in od.values()
            for v in (entry.subindices.values() if hasattr(entry, "subindices") else (entry,))
        }

    ours = node_dictionary(DEFAULT_EDS_PATH, node_id)
    canopens = canopen.import_od(str(DEFAULT_EDS_PATH), node_id)
    assert entries(ours) == entries(canopens)
    assert ours.node_id == canopens.node_id
    assert ours[0x1800][1].default & STANDARD_ID_MASK == cob_id(FunctionCode.TPDO1, node_id)
    assert node_dictionary(DEFAULT_EDS_PATH, node_id) is not ours, "each node its own, to change freely"
