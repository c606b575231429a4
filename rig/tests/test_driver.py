"""The lockstep driver's frame handling and its History, against a scripted in-process link
(exact frames, no threads, no bus): what a cycle takes, what it refuses, and how values are
stored per PDO; and the driver of a checker that goes on after a problem (`on_problem`), keeps
no history and listens to other frames (the soak's)."""

from __future__ import annotations

import dataclasses
import struct
from collections import deque
from collections.abc import Callable, Sequence

import canopen
import numpy as np
import pytest

from boardproto.cia301 import SYNC_COB_ID, NmtState, emcy_cob_id, heartbeat_cob_id
from hilrig.engine.driver import History
from hilrig.engine.lockstep import CycleProblem, LockstepDriver
from hilrig.engine.rig import DEFAULT_EDS_PATH
from hilrig.errors import LockstepError, PdoMappingError
from hilrig.plants import JointParams, RawSensors
from hilrig.plants.joint import JointModel
from hilrig.table import BOARD_TABLE, RigTable
from hilrig.wire.transport import PdoDirection, PdoLayout, compile_pdos, parse_frame

NODE_ID = 0x10
EMCY = emcy_cob_id(NODE_ID)
HEARTBEAT = heartbeat_cob_id(NODE_ID)
SENSORS, SETPOINTS = (BOARD_TABLE.rpdo(n).cob_id(NODE_ID) for n in (1, 2))
TPDO1, TPDO3, TPDO6, TPDO8 = (BOARD_TABLE.tpdo(n).cob_id(NODE_ID) for n in (1, 3, 6, 8))


class ScriptedLink:
    """Answers each SYNC with the TPDOs due at it; `script(sync_number, frames)` may change the
    answer (drop, duplicate, shorten, add frames)."""

    def __init__(self, tpdos: list[PdoLayout]) -> None:
        self.tpdos = tpdos
        self.out: deque[tuple[int, bytes]] = deque()
        self.sent: list[tuple[int, bytes]] = []
        self.sync_number = 0
        self.script: Callable[[int, list[tuple[int, bytes]]], list[tuple[int, bytes]]] = lambda n, f: f

    def send(self, frame: bytes) -> None:
        cob_id, data = parse_frame(frame)
        self.sent.append((cob_id, data))
        if cob_id == SYNC_COB_ID:
            self.sync_number += 1
            due = [(p.cob_id, bytes(range(p.length))) for p in self.tpdos if p.due_at_sync(self.sync_number)]
            self.out.extend(self.script(self.sync_number, due))

    def recv(self, timeout_s: float) -> tuple[int, bytes] | None:
        return self.out.popleft() if self.out else None

    def close(self) -> None:
        pass


class StubNode:
    node_id = NODE_ID
    last_heartbeat = None

    def __init__(self) -> None:
        network = canopen.Network()
        remote = canopen.RemoteNode(NODE_ID, str(DEFAULT_EDS_PATH))
        network.add_node(remote)
        remote.rpdo.read(from_od=True)
        remote.tpdo.read(from_od=True)
        self.rpdos = compile_pdos(PdoDirection.RPDO, remote.rpdo.map)
        self.tpdos = compile_pdos(PdoDirection.TPDO, remote.tpdo.map)
        self.table = RigTable.load()
        self.link = ScriptedLink([p for p in self.tpdos.values() if p.is_cyclic])
        self.emcy: list[bytes] = []
        self.receive_ids: list[int] = []

    def open_link(self, receive_ids: list[int]) -> ScriptedLink:
        self.receive_ids = receive_ids
        return self.link

    def emcy_received(self, data: bytes) -> None:
        self.emcy.append(data)


@pytest.fixture
def driver() -> LockstepDriver:
    params = JointParams()
    node = StubNode()
    driver = LockstepDriver(node, JointModel.of(params, 1), period_us=1000, tpdo_timeout_s=0.5)  # type: ignore[arg-type]
    driver.configure()
    driver.node_entered(NmtState.OPERATIONAL)
    return driver


def _link(driver: LockstepDriver) -> ScriptedLink:
    return driver.node.link  # type: ignore[attr-defined,return-value]


def test_a_cycle_sends_sensors_setpoints_and_sync_and_takes_every_due_tpdo(driver) -> None:
    result = driver.step()
    sent_ids = [cob_id for cob_id, _ in _link(driver).sent]
    assert sent_ids == [SENSORS, SETPOINTS, SYNC_COB_ID]  # sensor RPDO, setpoint stream, SYNC counter 1
    assert _link(driver).sent[-1] == (SYNC_COB_ID, b"\x01")
    assert sorted(p.number for p, _ in result.received_rows) == [1, 2, 3, 4, 5, 6, 7]
    assert result.received["motor_duty"] == int.from_bytes(b"\x00\x01", "little", signed=True)
    assert driver.cycle == 1 and driver.malformed_frames == 0


def test_tpdo_of_the_wrong_length_is_counted_and_reported_for_its_cycle(driver) -> None:
    _link(driver).script = lambda n, frames: [(c, d[:-1]) if c == TPDO1 else (c, d) for c, d in frames]
    with pytest.raises(
        LockstepError, match=r"cycle 0 \(t = 0 s\): TPDO1 \(0x190\) arrived with 2 bytes, its mapping has 3"
    ):
        driver.step()
    assert driver.malformed_frames == 1


def test_a_tpdo_twice_is_reported(driver) -> None:
    _link(driver).script = lambda n, frames: [*frames, frames[2]]
    with pytest.raises(LockstepError, match=r"TPDO3 \(0x390\) arrived twice"):
        driver.step()


def test_a_failed_cycle_leaves_none_of_its_rows_in_the_history(driver) -> None:
    driver.step()
    before = driver.history.mark().rows
    _link(driver).script = lambda n, frames: [*frames, frames[2]]  # every due TPDO in, then one twice
    with pytest.raises(LockstepError, match="arrived twice"):
        driver.step()
    assert driver.history.mark().rows == before
    assert driver.history.received("motor_duty")[0].tolist() == [0.0]


def test_a_missing_tpdo_times_out_naming_it(driver) -> None:
    _link(driver).script = lambda n, frames: [f for f in frames if f[0] != TPDO6]
    with pytest.raises(LockstepError, match=r"TPDO6 \(0x2D0\) did not arrive within 0.5 s"):
        driver.step()


def test_emcy_among_the_tpdos_is_dispatched_and_the_cycle_completes(driver) -> None:
    emcy = bytes.fromhex("1082011014000000")
    _link(driver).script = lambda n, frames: [frames[0], (EMCY, emcy), *frames[1:]]
    driver.step()
    assert driver.node.emcy == [emcy]  # type: ignore[attr-defined]


def test_emcy_between_cycles_is_dispatched_by_poll_and_a_late_tpdo_is_reported_next_cycle(driver) -> None:
    driver.step()
    link = _link(driver)
    link.out.extend([(EMCY, bytes(8)), (TPDO1, bytes(3))])
    driver.poll()
    assert driver.node.emcy == [bytes(8)]  # type: ignore[attr-defined]
    with pytest.raises(LockstepError, match=r"cycle 1 .*TPDO1 \(0x190\) arrived between SYNCs"):
        driver.step()


def test_history_keeps_rows_per_pdo_and_merges_a_name_carried_twice() -> None:
    first = PdoLayout(PdoDirection.TPDO, 1, TPDO1, True, 1, ("a", "b"), ("h", "f"))
    second = PdoLayout(PdoDirection.TPDO, 9, TPDO8, True, 2, ("b",), ("f",))
    history = History(period_us=1000)
    for cycle in range(4):
        rows = [(first, (cycle, cycle * 0.5))]
        if cycle % 2:
            rows.append((second, (100.0 + cycle,)))
        history.record_rows(cycle, rows, ())
    t, b = history.received("b")
    assert list(t) == [0.0, 0.001, 0.001, 0.002, 0.003, 0.003]
    assert list(b) == [0.0, 0.5, 101.0, 1.0, 1.5, 103.0]
    assert history.latest_received("b") == 103.0 and history.latest_received("a") == 3
    twin = dataclasses.replace(first)  # the same mapping read again after a restart
    history.record_rows(4, [(twin, (4, 2.0))], ())
    assert np.array_equal(history.received("a")[1], [0, 1, 2, 3, 4])
    assert not history.has_received("c") and not history.has_sent("a")


def test_history_gives_back_exactly_the_numbers_the_bus_carried() -> None:
    # Rows are stored as the payloads the bus carried: every type comes back as the number it
    # was (a REAL32 as its float32 value), widened to int64, float64 or bool for arithmetic.
    names, formats = ("i", "u", "flag", "x", "p"), ("h", "H", "?", "f", "i")
    layout = PdoLayout(PdoDirection.TPDO, 2, TPDO6, True, 1, names, formats)
    rows = [(-32768, 65535, True, 0.1, -(2**31)), (7, 0, False, -2.5e-3, 2**31 - 1)]
    history = History(period_us=500)
    for cycle, values in enumerate(rows, start=10):
        history.record_rows(cycle, [(layout, values)], ())
    as_float32 = struct.unpack("<f", struct.pack("<f", 0.1))[0]
    t, i = history.received("i")
    assert t.tolist() == [0.005, 0.0055] and i.dtype == np.int64 and i.tolist() == [-32768, 7]
    assert history.received("u")[1].tolist() == [65535, 0]
    assert history.received("flag")[1].dtype == np.bool_
    x = history.received("x")[1]
    assert x.dtype == np.float64 and x[0] == as_float32
    assert history.latest_received("x") == struct.unpack("<f", struct.pack("<f", -2.5e-3))[0]
    assert history.latest_received("flag") is False
    assert history.received("p")[1].tolist() == [-(2**31), 2**31 - 1]

    start = history.mark()
    history.record_rows(12, [(layout, (1, 2, True, 3.0, 4))], ())
    ((block_layout, cycles, matrix),) = history.blocks_between(start, history.mark())
    assert (
        block_layout is layout and cycles.tolist() == [12] and matrix.tolist() == [[1.0, 2.0, 1.0, 3.0, 4.0]]
    )
    held = history.received("i")  # what a reader holds never stops the rows from growing
    history.record_rows(13, [(layout, (2, 2, False, 3.0, 5))], ())
    assert held[1].tolist() == [-32768, 7, 1] and history.received("i")[1].tolist() == [-32768, 7, 1, 2]

    history.take_back(layout, 12)  # not the last row's cycle: nothing to take back
    history.take_back(layout, 13)
    assert history.received("i")[1].tolist() == [-32768, 7, 1]


# --- A driver that goes on after a problem, keeps no history, listens (the soak's) ---------
@pytest.fixture
def checking() -> tuple[LockstepDriver, list[CycleProblem], list[tuple[int, bytes]]]:
    params = JointParams()
    driver = LockstepDriver(
        StubNode(), JointModel.of(params, 1), period_us=1000, tpdo_timeout_s=0.5,
        keep_history=False,
    )  # type: ignore[arg-type]  # fmt: skip
    problems: list[CycleProblem] = []
    heard: list[tuple[int, bytes]] = []
    driver.on_problem = problems.append
    driver.listen(HEARTBEAT, lambda cob_id, data: heard.append((cob_id, data)))
    driver.configure()
    driver.node_entered(NmtState.OPERATIONAL)
    return driver, problems, heard


def test_with_on_problem_a_refused_tpdo_is_reported_and_the_cycle_takes_the_rest(checking) -> None:
    driver, problems, _ = checking
    _link(driver).script = lambda n, frames: [(TPDO1, b"\x00"), *frames, frames[2]]
    result = driver.step()
    assert [(p.cycle, p.what, p.refused and p.refused.number) for p in problems] == [
        (0, "TPDO1 (0x190) arrived with 1 bytes, its mapping has 3", 1),
        (0, "TPDO3 (0x390) arrived twice", 3),
    ]
    assert len(result.values_by_cob_id()) == 7 and driver.cycle == 1 and driver.malformed_frames == 1
    assert problems[1].error().args == ("cycle 0 (t = 0 s): TPDO3 (0x390) arrived twice",)


def test_with_on_problem_missing_tpdos_end_their_cycle_and_the_next_runs(checking) -> None:
    driver, problems, _ = checking
    _link(driver).script = lambda n, frames: [f for f in frames if f[0] != TPDO6 or n != 1]
    result = driver.step()
    (lost,) = problems
    assert [p.number for p in lost.missing] == [6] and [p.number for p in lost.received] == [1, 2, 3, 4, 5, 7]
    assert lost.what == "TPDO6 (0x2D0) did not arrive within 0.5 s" and lost.refused is None
    assert TPDO6 not in result.values_by_cob_id() and driver.cycle == 1
    assert len(driver.step().values_by_cob_id()) == 7 and len(problems) == 1


def test_late_tpdos_are_handed_back_and_listeners_get_their_frames(checking) -> None:
    driver, problems, heard = checking
    assert HEARTBEAT in driver.node.receive_ids  # type: ignore[attr-defined]
    _link(driver).script = lambda n, frames: [(HEARTBEAT, b"\x05"), *frames]
    driver.step()
    _link(driver).out.extend([(TPDO1, bytes(3)), (HEARTBEAT, b"\x05")])
    assert [(pdo.number, data) for pdo, data in driver.take_late_tpdos()] == [(1, bytes(3))]
    assert heard == [(HEARTBEAT, b"\x05")] * 2
    driver.step()
    assert problems == []  # the late one was handed back, not kept for this cycle


def test_a_tpdo_while_the_node_is_not_operational_is_refused_as_such(checking) -> None:
    driver, problems, _ = checking
    driver.node_entered(NmtState.STOPPED)
    _link(driver).script = lambda n, frames: frames[:1]  # a node that answers while stopped
    driver.step()
    assert [p.what for p in problems] == [
        "TPDO1 (0x190) arrived while the node is not operational (nothing is due)"
    ]


def test_a_history_that_keeps_nothing_stays_empty(checking) -> None:
    driver = checking[0]
    for _ in range(3):
        driver.step()
    history = driver.history
    assert history.cycles == 0 and history.layouts() == [] and not history.has_received("motor_duty")


# --- Any plant: the driver knows it by the interface ----------------------------------------
class TwoOutputPlant:
    """A plant of the interface consuming fields of two TPDOs, recording what it is given."""

    sensor_fields = tuple(RawSensors.__dataclass_fields__)
    actuator_fields = ("motor_duty", "joint_torque")
    truth_fields = ("steps",)

    def __init__(self) -> None:
        self.applied: list[tuple[float | int, ...] | None] = []
        self.steps: list[float] = []

    def sense(self) -> RawSensors:
        return RawSensors(1, 2, 3, -4)

    def truth(self) -> int:
        return len(self.steps)

    def truth_matrix(self, snapshots: Sequence[int]) -> np.ndarray:
        return np.asarray(snapshots, dtype=np.float64).reshape(-1, 1)

    def truth_parameters(self) -> dict[str, float]:
        return {}

    def apply(self, outputs: tuple[float | int, ...] | None) -> None:
        self.applied.append(outputs)

    def step(self, dt_s: float) -> None:
        self.steps.append(dt_s)


def test_a_plant_gets_its_actuator_fields_from_the_tpdos_that_carry_them() -> None:
    plant = TwoOutputPlant()
    driver = LockstepDriver(StubNode(), plant, period_us=500, tpdo_timeout_s=0.5)  # type: ignore[arg-type]
    driver.configure()
    driver.node_entered(NmtState.OPERATIONAL)
    tpdos = {p.cob_id: p for p in driver.node.tpdos.values()}
    sent = {c: tpdos[c].unpack(bytes(range(tpdos[c].length))) for c in (TPDO1, TPDO3)}
    result = driver.step()
    expected = (sent[TPDO1][0], sent[TPDO3][0])
    assert result.outputs == expected and plant.applied == [expected] and plant.steps == [0.0005]
    rpdo1, frame = driver.node.rpdos[1], RawSensors(1, 2, 3, -4)
    assert _link(driver).sent[0] == (SENSORS, rpdo1.codec.pack(*(getattr(frame, n) for n in rpdo1.names)))
    assert driver.history.truth("steps")[1].tolist() == [0.0]

    driver.on_problem = lambda problem: None  # TPDO3 missing: the cycle ends without it
    _link(driver).script = lambda n, frames: [f for f in frames if f[0] != TPDO3]
    driver.tpdo_timeout_s = 0.0
    assert driver.step().outputs is None and plant.applied[-1] is None  # not every field came


def test_a_plant_whose_field_no_tpdo_carries_is_refused_naming_it() -> None:
    plant = TwoOutputPlant()
    plant.actuator_fields = ("motor_duty", "gear_ratio")  # type: ignore[assignment]
    driver = LockstepDriver(StubNode(), plant, period_us=1000)  # type: ignore[arg-type]
    with pytest.raises(PdoMappingError, match="HIL output gear_ratio is in no enabled TPDO"):
        driver.configure()


class TableStreaming:
    """The demo table with another setpoint stream (a board that streams these fields, or none)."""

    def __init__(self, table: RigTable, *streamed: str) -> None:
        self._table = table
        self.setpoint_stream = streamed

    def __getattr__(self, name: str) -> object:
        return getattr(self._table, name)


def test_a_board_that_streams_nothing_has_no_stream_and_sends_rpdos_when_changed() -> None:
    node = StubNode()
    node.table = TableStreaming(node.table)  # type: ignore[assignment]
    driver = LockstepDriver(node, JointModel.of(JointParams(), 1), period_us=1000)  # type: ignore[arg-type]
    driver.configure()
    driver.node_entered(NmtState.OPERATIONAL)
    driver.step()
    assert [c for c, _ in _link(driver).sent] == [SENSORS, SYNC_COB_ID]  # the sensors alone
    _link(driver).sent.clear()
    driver.set_rpdo_value("position_setpoint", 0.5)
    driver.step()
    changed = BOARD_TABLE.rpdo(3).cob_id(NODE_ID)
    assert [c for c, _ in _link(driver).sent] == [SENSORS, changed, SYNC_COB_ID]


def test_the_stream_is_what_the_table_streams_not_the_demos_field_names() -> None:
    node = StubNode()
    node.table = TableStreaming(node.table, "position_setpoint")  # type: ignore[assignment]
    driver = LockstepDriver(node, JointModel.of(JointParams(), 1), period_us=1000)  # type: ignore[arg-type]
    driver.configure()
    driver.node_entered(NmtState.OPERATIONAL)
    driver.step()
    driver.step()
    streamed = BOARD_TABLE.rpdo(3).cob_id(NODE_ID)  # control_mode and position_setpoint
    assert [c for c, _ in _link(driver).sent][-3:] == [SENSORS, streamed, SYNC_COB_ID]


def test_the_demo_table_streams_its_two_setpoints() -> None:
    assert BOARD_TABLE.setpoint_stream == ("velocity_setpoint", "torque_setpoint")


def test_a_setpoint_field_of_the_table_in_no_rpdo_is_refused_naming_it(driver) -> None:
    driver.node.rpdos[2] = dataclasses.replace(driver.node.rpdos[2], enabled=False)
    with pytest.raises(PdoMappingError, match="setpoint velocity_setpoint is in no enabled RPDO"):
        driver.configure()


def test_an_integer_field_of_an_rpdo_takes_whole_numbers_and_names_itself_otherwise() -> None:
    from hilrig.engine.driver import wire_value

    assert (
        wire_value("target_position", 0.0, "i") == 0 and type(wire_value("target_position", 0.0, "i")) is int
    )
    assert wire_value("controlword", 15, "H") == 15
    assert wire_value("velocity_setpoint", 2.5, "f") == 2.5
    with pytest.raises(ValueError, match=r"^target_position: an integer field, got 1\.5$"):
        wire_value("target_position", 1.5, "i")
