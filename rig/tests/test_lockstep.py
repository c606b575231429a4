"""The lockstep driver and the scenario API against an in-process fake node on python-can's
virtual bus: no firmware, no kernel CAN. Wire-level checks decode the frames with cantools and
the generated DBC, independently of canopen's PDO maps that packed them."""

from __future__ import annotations

import itertools
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import can
import cantools
import numpy as np
import pytest

from boardproto.cia301 import NMT_COB_ID, SYNC_COB_ID, NmtCommand, SdoAbortCode
from hilrig.engine.rig import DEFAULT_EDS_PATH, Rig
from hilrig.errors import (
    FieldAccessError,
    FieldNameError,
    FirmwareError,
    LockstepError,
    NodeSilentError,
    PdoMappingError,
    ScenarioTimeoutError,
    SdoAbortError,
)
from hilrig.plants import JointParams, JointPlant, RawSensors, SensorModel, duty_from_motor_duty
from hilrig.session.fake_node import DUTY_PER_VELOCITY_SETPOINT, FakeJointNode
from hilrig.table import BOARD_TABLE, ControlMode, EmcyCode, LedPattern, RigTable

DBC_PATH = DEFAULT_EDS_PATH.with_name("board.dbc")
PARAMS = JointParams.fast_thermal()
SEED = 7
_channels = itertools.count()
NODE_ID = BOARD_TABLE.node.default_node_id  # the fake node's
_TPDO_IDS = {pdo.cob_id(NODE_ID) for pdo in BOARD_TABLE.tpdos if pdo.enabled}
OVER_TEMPERATURE = BOARD_TABLE.emcy("over_temperature")
WINDING_TEMPERATURE = BOARD_TABLE.field("winding_temperature").index  # what the EMCY is about


@pytest.fixture(scope="session")
def table() -> RigTable:
    return RigTable.load()


@pytest.fixture(scope="session")
def dbc() -> cantools.database.can.Database:
    return cantools.database.load_file(str(DBC_PATH))


@dataclass
class Bench:
    rig: Rig
    fake: FakeJointNode
    spy: can.BusABC  # sees every frame of the bus, for wire-level checks

    def frames(self) -> list[can.Message]:
        frames = []
        while (message := self.spy.recv(timeout=0)) is not None:
            frames.append(message)
        return frames


def _buses(count: int) -> list[can.BusABC]:
    channel = f"hilrig-test-{next(_channels)}"
    return [can.Bus(interface="virtual", channel=channel) for _ in range(count)]


@pytest.fixture
def unstarted(table: RigTable) -> Iterator[Bench]:
    rig_bus, fake_bus, spy = _buses(3)
    fake = FakeJointNode(fake_bus, table=table)
    rig = Rig(rig_bus, table=table, params=PARAMS, seed=SEED, tpdo_timeout_s=0.5, activity=fake.activity)
    fake.boot()
    yield Bench(rig, fake, spy)
    rig.close()
    fake.close()
    for bus in (rig_bus, fake_bus, spy):
        bus.shutdown()


@pytest.fixture
def bench(unstarted: Bench) -> Bench:
    unstarted.rig.start()
    unstarted.frames()  # start-up traffic is not what the tests look at
    return unstarted


# --- Cycles and time ---------------------------------------------------------------------
def test_counts_cycles_and_keeps_exact_simulation_time(bench: Bench) -> None:
    bench.rig.run(seconds=0.025)
    assert bench.rig.cycle == 25
    assert bench.rig.t == 0.025
    assert bench.fake.syncs == list(range(1, 26))
    t, duty = bench.rig.history("motor_duty")
    np.testing.assert_array_equal(t, np.arange(25) / 1000)
    assert len(duty) == 25
    t_truth, _ = bench.rig.truth("load_velocity")
    np.testing.assert_array_equal(t_truth, t)


def test_waits_for_slow_tpdos_only_at_their_sync(bench: Bench) -> None:
    # TPDO8 has transmission type 10: due at SYNC 10, 20, ... since the node went operational.
    bench.rig.run(cycles=25)
    t, _ = bench.rig.history("winding_temperature")
    np.testing.assert_allclose(t, [0.009, 0.019])


def test_sync_counter_wraps_after_240(bench: Bench) -> None:
    bench.rig.run(cycles=242)
    assert bench.fake.syncs[238:] == [239, 240, 1, 2]
    sync_payloads = [m.data[0] for m in bench.frames() if m.arbitration_id == SYNC_COB_ID]
    assert sync_payloads[238:] == [239, 240, 1, 2]


def test_sync_count_restarts_when_the_node_is_started_again(bench: Bench) -> None:
    bench.rig.run(cycles=5)
    bench.rig.nmt(NmtCommand.STOP)
    bench.rig.run(cycles=3)  # nothing is due from a stopped node, and the bridge is off
    _, applied = bench.rig.truth("applied_duty")
    assert list(applied[6:]) == [0.0, 0.0]
    bench.rig.nmt(NmtCommand.START)
    bench.rig.run(cycles=10)
    t, _ = bench.rig.history("winding_temperature")
    np.testing.assert_allclose(t, [0.017])  # the 10th SYNC after the restart


# --- What goes out and what comes back ---------------------------------------------------
def test_rpdo1_carries_the_physics_raw_values_and_tpdo1_duty_drives_the_plant(
    bench: Bench, dbc: cantools.database.can.Database
) -> None:
    bench.rig.set("velocity_setpoint", 20.0)
    bench.rig.run(cycles=40)
    cycles = _split_by_sync(bench.frames())
    assert len(cycles) == 40

    # An independent plant with the same parameters and seed, driven by the duties on the wire.
    plant, sensors = JointPlant(PARAMS), SensorModel(PARAMS, SEED)
    for before_sync, after_sync in cycles:
        rpdo1 = _decode(dbc, before_sync, "RPDO1")
        assert RawSensors(**rpdo1) == sensors.read(plant.state)
        tpdo1 = _decode(dbc, after_sync, "TPDO1")
        assert tpdo1["motor_duty"] == 20.0 * DUTY_PER_VELOCITY_SETPOINT
        plant.step(1e-3, duty_from_motor_duty(int(tpdo1["motor_duty"])))
    assert bench.rig.state == plant.state
    assert plant.state.motor_angle_rad > 0.1  # the duty really moved it, so encoders changed


def test_setpoint_stream_goes_out_every_cycle_with_the_latest_value(
    bench: Bench, dbc: cantools.database.can.Database
) -> None:
    bench.rig.set("velocity_setpoint", 10.0)
    bench.rig.at(0.010, lambda rig: rig.set("velocity_setpoint", -5.0))
    bench.rig.run(cycles=20)
    on_wire = [
        _decode(dbc, before, "RPDO2")["velocity_setpoint"] for before, _ in _split_by_sync(bench.frames())
    ]
    assert on_wire == [10.0] * 10 + [-5.0] * 10
    _, duty = bench.rig.history("motor_duty")
    assert list(duty) == [2000] * 10 + [-1000] * 10
    _, sent = bench.rig.sent("velocity_setpoint")
    assert list(sent) == on_wire


def test_other_rpdos_go_out_once_after_a_change(bench: Bench, dbc: cantools.database.can.Database) -> None:
    bench.rig.run(cycles=3)
    bench.rig.set("control_mode", ControlMode.VELOCITY)
    bench.rig.run(cycles=3)
    rpdo3 = BOARD_TABLE.rpdo(3).cob_id(NODE_ID)
    frames = [m for m in bench.frames() if m.arbitration_id == rpdo3]
    assert len(frames) == 1
    decoded = dbc.decode_message("RPDO3", frames[0].data, decode_choices=False)  # numbers, not names
    assert decoded["control_mode"] == float(ControlMode.VELOCITY)
    t, mode = bench.rig.sent("control_mode")
    assert (list(t), list(mode)) == ([0.003], [float(ControlMode.VELOCITY)])


def test_field_returns_the_latest_tpdo_value(bench: Bench) -> None:
    bench.rig.run(cycles=5)
    raw = bench.fake.last_inputs["motor_encoder_counts"]
    assert bench.rig.field("motor_velocity") == float(raw)
    assert bench.rig.field("led_pattern") == LedPattern.ON


def test_silenced_setpoint_stream_stops_rpdo2(bench: Bench) -> None:
    rpdo2 = BOARD_TABLE.rpdo(2).cob_id(NODE_ID)
    bench.rig.pause_rpdo(2)
    bench.rig.run(cycles=3)
    assert not [m for m in bench.frames() if m.arbitration_id == rpdo2]
    bench.rig.resume_rpdo(2)
    bench.rig.run(cycles=1)
    assert len([m for m in bench.frames() if m.arbitration_id == rpdo2]) == 1


def test_sensor_override_replaces_what_is_sent(bench: Bench, dbc: cantools.database.can.Database) -> None:
    bench.rig.override_sensors(
        lambda raw: RawSensors(
            raw.motor_encoder_counts, raw.output_encoder_counts, 4095, raw.motor_current_adc
        )
    )
    bench.rig.run(cycles=2)
    adc = [_decode(dbc, before, "RPDO1")["thermistor_adc"] for before, _ in _split_by_sync(bench.frames())]
    assert adc == [4095, 4095]
    with pytest.raises(FieldAccessError, match="override_sensors"):
        bench.rig.set("thermistor_adc", 4095)


# --- Failures name the cycle -------------------------------------------------------------
def test_missing_tpdo_raises_lockstep_error_naming_cycle_time_and_pdo(bench: Bench) -> None:
    bench.fake.drop = lambda sync_number, tpdo: sync_number == 7 and tpdo == 3
    bench.rig.driver.tpdo_timeout_s = 0.2
    with pytest.raises(
        LockstepError,
        match=re.escape("cycle 6 (t = 0.006 s): TPDO3 (0x390) did not arrive: the firmware sat idle for"),
    ):
        bench.rig.run(cycles=10)
    assert bench.rig.cycle == 6
    # The TPDOs that did arrive in the failed cycle are not in the history: it ends at cycle 5.
    t, _ = bench.rig.history("motor_duty")  # TPDO1, in before the missing TPDO3
    assert t[-1] == pytest.approx(0.005)


def test_missing_slow_tpdo_is_noticed_at_its_sync(bench: Bench) -> None:
    bench.fake.drop = lambda sync_number, tpdo: tpdo == 8
    bench.rig.driver.tpdo_timeout_s = 0.2
    bench.rig.run(cycles=9)
    with pytest.raises(LockstepError, match=re.escape("cycle 9 (t = 0.009 s): TPDO8 (0x4D0)")):
        bench.rig.run(cycles=1)


def test_tpdo_that_is_not_due_raises(bench: Bench) -> None:
    bench.fake.local.tpdo.map[8].trans_type = 1  # the node sends what the rig was told is slow
    with pytest.raises(
        LockstepError, match=re.escape("cycle 0 (t = 0 s): TPDO8 (0x4D0) arrived but is not due at SYNC 1")
    ):
        bench.rig.run(cycles=1)


def test_dead_firmware_reads_as_firmware_error_not_timeout(unstarted: Bench) -> None:
    def liveness() -> None:
        raise FirmwareError("joint-firmware exited with code 1")

    unstarted.rig.driver.liveness = liveness
    unstarted.rig.start()
    unstarted.fake.drop = lambda sync_number, tpdo: True
    with pytest.raises(FirmwareError, match="exited"):
        unstarted.rig.run(cycles=1)


# --- Start-up ----------------------------------------------------------------------------
def test_start_puts_the_node_operational(unstarted: Bench) -> None:
    unstarted.rig.start()
    nmt = [(m.arbitration_id, bytes(m.data)) for m in unstarted.frames() if m.arbitration_id == NMT_COB_ID]
    assert nmt[-1] == (NMT_COB_ID, bytes([NmtCommand.START, NODE_ID]))
    unstarted.rig.run(cycles=1)  # the fake answers SYNC only once it is operational
    assert unstarted.fake.state.name == "OPERATIONAL"
    # The hang guard sees the thread that answered, as it sees a firmware process.
    assert unstarted.fake.activity() is not None


def test_start_refuses_an_actuator_tpdo_that_is_not_sent_every_sync(unstarted: Bench) -> None:
    unstarted.fake.set_pdo_parameter(BOARD_TABLE.tpdo(1).communication_index, 2, 10)
    with pytest.raises(
        PdoMappingError, match=re.escape("TPDO1 (0x190) carries motor_duty with transmission type 10")
    ):
        unstarted.rig.start()


def test_start_refuses_a_mapping_without_the_sensor_inputs(unstarted: Bench) -> None:
    unstarted.fake.set_pdo_parameter(BOARD_TABLE.rpdo(1).mapping_index, 0, 3)  # RPDO1 loses motor_current_adc
    with pytest.raises(PdoMappingError, match="HIL input motor_current_adc is in no enabled RPDO"):
        unstarted.rig.start()


def test_start_refuses_two_rpdos_on_one_cob_id(unstarted: Bench) -> None:
    rpdo2, rpdo3 = BOARD_TABLE.rpdo(2), BOARD_TABLE.rpdo(3)
    unstarted.fake.set_pdo_parameter(rpdo3.communication_index, 1, rpdo2.cob_id(NODE_ID))
    with pytest.raises(PdoMappingError, match=re.escape(f"RPDO2 (0x{rpdo2.cob_id(NODE_ID):03X}) and RPDO3")):
        unstarted.rig.start()


def test_start_without_a_node_is_a_bounded_timeout(table: RigTable) -> None:
    (bus,) = _buses(1)
    rig = Rig(bus, table=table, boot_timeout_s=0.05, sdo_timeout_s=0.05)
    try:
        with pytest.raises(NodeSilentError, match=r"no boot-up or heartbeat within 0\.05 s") as info:
            rig.start()
        assert isinstance(info.value, TimeoutError)
    finally:
        rig.close()
        bus.shutdown()


def test_start_stops_waiting_once_the_firmware_process_is_gone(table: RigTable) -> None:
    """A firmware that cannot start (an ASan build under user-mode Linux, a missing library)
    is reported by its exit at once, not as a silent node at the end of the boot bound."""
    (bus,) = _buses(1)
    calls = []

    def firmware_exited() -> None:
        calls.append(1)
        raise FirmwareError("joint-firmware exited with code 1; last lines of fw.log:\nShadow memory")

    rig = Rig(bus, table=table, boot_timeout_s=5.0, sdo_timeout_s=0.05, liveness=firmware_exited)
    try:
        with pytest.raises(FirmwareError, match="exited with code 1"):
            rig.start()
        assert calls == [1]
    finally:
        rig.close()
        bus.shutdown()


# --- Names, SDO, EMCY, events ------------------------------------------------------------
@pytest.mark.parametrize(
    ("call", "suggestion"),
    [
        (lambda rig: rig.set("velocity_setpont", 1.0), "velocity_setpoint"),
        (lambda rig: rig.field("motor_velocty"), "motor_velocity"),
        (lambda rig: rig.history("joint_torqe"), "joint_torque"),
        (lambda rig: rig.truth("load_velocty"), "load_velocity"),
        (lambda rig: rig.check_names("motor_duty", "led_patern"), "led_pattern"),
    ],
)
def test_typo_in_a_name_fails_with_close_matches(bench: Bench, call, suggestion: str) -> None:
    with pytest.raises(FieldNameError, match=f"did you mean .*'{suggestion}'") as info:
        call(bench.rig)
    assert isinstance(info.value, KeyError)


def test_truth_accepts_full_and_short_names(bench: Bench) -> None:
    bench.rig.set("velocity_setpoint", 20.0)
    bench.rig.run(cycles=5)
    np.testing.assert_array_equal(
        bench.rig.truth("load_velocity")[1], bench.rig.truth("load_velocity_rad_s")[1]
    )


def test_sdo_write_refused_by_the_node_is_explained(bench: Bench) -> None:
    with pytest.raises(SdoAbortError) as info:
        bench.rig.set("velocity_kp", 99.0)
    assert str(info.value) == "write velocity_kp: 0x06090031 value too high (max 10.0)"
    assert info.value.abort_code == SdoAbortCode.VALUE_TOO_HIGH
    read_only = "write motor_velocity: 0x06010002 object is read-only"
    with pytest.raises(SdoAbortError, match=re.escape(read_only)):
        bench.rig.set("motor_velocity", 1.0)


def test_sdo_write_and_read_back_by_name(bench: Bench) -> None:
    bench.rig.set("velocity_kp", 0.25)
    assert bench.rig.field("velocity_kp") == 0.25  # not in a TPDO: read by SDO


def test_emcy_is_recorded_with_cycle_and_time(bench: Bench) -> None:
    bench.rig.run(cycles=5)
    about = WINDING_TEMPERATURE.to_bytes(2, "little") + bytes(3)
    bench.fake.send_emcy(EmcyCode.OVER_TEMPERATURE, OVER_TEMPERATURE.error_register, about)
    bench.rig.run(cycles=1)  # frames arrive in order: the EMCY before cycle 5's TPDOs
    (emcy,) = bench.rig.emcy
    assert (emcy.code, emcy.register, emcy.cycle, emcy.time_s) == (
        EmcyCode.OVER_TEMPERATURE,
        OVER_TEMPERATURE.error_register,
        5,
        0.005,
    )
    assert emcy.object_index == WINDING_TEMPERATURE
    assert "Temperature" in str(emcy)


def test_events_fire_at_their_simulation_time_in_order(bench: Bench) -> None:
    fired: list[tuple[str, int, float]] = []
    bench.rig.at(0.005, lambda rig: fired.append(("b", rig.cycle, rig.t)))
    bench.rig.at(0.003, lambda rig: fired.append(("a", rig.cycle, rig.t)))
    bench.rig.at(0.010, lambda rig: fired.append(("end", rig.cycle, rig.t)))
    bench.rig.run(seconds=0.010)
    assert fired == [("a", 3, 0.003), ("b", 5, 0.005), ("end", 10, 0.01)]
    with pytest.raises(ValueError, match="already past"):
        bench.rig.at(0.002, lambda rig: None)


def test_run_until_counts_in_simulation_time(bench: Bench) -> None:
    assert bench.rig.run_until(lambda rig: rig.cycle >= 7, within_s=0.010) == 0.007
    with pytest.raises(
        ScenarioTimeoutError,
        match=re.escape("expected never within 0.005 s, not met at t = 0.012 s (cycle 12)"),
    ):
        bench.rig.run_until(lambda rig: False, within_s=0.005, what="never")


# --- Helpers -----------------------------------------------------------------------------
def _split_by_sync(frames: list[can.Message]) -> list[tuple[list[can.Message], list[can.Message]]]:
    """Per cycle: the frames before its SYNC (RPDOs) and after it (TPDOs)."""
    cycles: list[tuple[list[can.Message], list[can.Message]]] = []
    pending: list[can.Message] = []
    for message in frames:
        if message.arbitration_id == SYNC_COB_ID:
            cycles.append((pending, []))
            pending = []
        elif cycles and message.arbitration_id in _TPDO_IDS:
            cycles[-1][1].append(message)
        else:
            pending.append(message)
    return cycles


def _decode(dbc: cantools.database.can.Database, frames: list[can.Message], name: str) -> dict:
    frame_id = dbc.get_message_by_name(name).frame_id
    (message,) = [m for m in frames if m.arbitration_id == frame_id]
    return dbc.decode_message(frame_id, message.data)


def test_dbc_is_where_the_rig_expects_it() -> None:
    assert Path(DBC_PATH).exists()
