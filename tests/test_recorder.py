"""The firmware's field recorder, end to end in lockstep: set up over SDO, triggered by a
velocity step, uploaded by SDO block transfer through python-canopen (`hilrig.apps.capture`), and
every captured sample equal to what the same fields' TPDOs carried in the same cycle."""

from __future__ import annotations

import struct

import canopen
import numpy as np
import pytest
from canopen.sdo import SdoClient
from conftest import EDS, FULL_MAPPING_ON_THE_IDEAL_BUS, TABLE

from boardproto.cia301 import SdoAbortCode
from boardproto.table import RecorderObject
from hilrig.apps.capture import CaptureSettings, RecorderClient
from hilrig.session.netns import PrivateBus
from hilrig.table import ControlMode

pytestmark = [pytest.mark.bus, FULL_MAPPING_ON_THE_IDEAL_BUS]

CHANNELS = (
    "motor_velocity",
    "output_velocity",
    "joint_torque",
    "spring_deflection",
    "motor_duty_command",
    "velocity_controller_output",
    "torque_controller_output",
    "output_position",
)
"""Eight fields every cycle's TPDOs carry (type 1), so the rig's history has each sample's twin."""
SAMPLES = 2000
PRE_TRIGGER_PERCENT = 10
STEP_AT_CYCLE = 400


@pytest.mark.requirement("REC_01", "SDO_05")
def test_a_triggered_capture_equals_the_lockstep_history_cycle_for_cycle(
    make_scenario, private_bus: PrivateBus
) -> None:
    rig = make_scenario().rig
    rig.set("control_mode", ControlMode.VELOCITY)
    rig.set("velocity_setpoint", 0.0)
    recorder = RecorderClient(rig.node, TABLE)
    recorder.configure(
        CaptureSettings(
            channels=CHANNELS,
            samples=SAMPLES,
            trigger="level",
            trigger_field="velocity_setpoint",
            level=1.0,
            edge="rising",
            pre_trigger_percent=PRE_TRIGGER_PERCENT,
        )
    )
    recorder.arm()
    rig.run(cycles=STEP_AT_CYCLE)
    assert recorder.progress().state == "armed", "no trigger before the step"
    rig.set("velocity_setpoint", 2.0)
    rig.run(cycles=SAMPLES)
    progress = recorder.progress()
    assert progress.state == "done", progress

    recording = recorder.upload()  # SDO block upload of the DOMAIN, with CRC
    assert recording.channels == tuple(TABLE.entry(name).index for name in CHANNELS)
    assert recording.sample_count == SAMPLES
    pre = SAMPLES * PRE_TRIGGER_PERCENT // 100
    assert recording.trigger_sample == pre
    assert not recording.periods_skipped

    # The firmware counts every SYNC it saw, the rig numbers its cycles from 0 with its first.
    rig_cycle_of = [recording.cycle_of(k) - 1 for k in range(recording.sample_count)]
    assert rig_cycle_of[pre] == STEP_AT_CYCLE, "the trigger is the cycle the step was sent in"
    period = rig.period_s
    for channel, name in enumerate(CHANNELS):
        t, values = rig.history(name)
        by_cycle = dict(zip(np.rint(t / period).astype(int).tolist(), values.tolist(), strict=True))
        captured = recording.column(channel)
        sent = [by_cycle[cycle] for cycle in rig_cycle_of]
        # Both are the firmware's REAL32: equal to the bit, not approximately.
        mismatches = [(c, a, b) for c, a, b in zip(rig_cycle_of, captured, sent, strict=True) if a != b]
        assert not mismatches, f"{name}: {len(mismatches)} samples differ, first {mismatches[:3]}"
    assert max(recording.column(0)) > 0.0, "the capture saw the motor speed up"

    # The same bytes by block upload through python-canopen as anyone uses it: a RemoteNode of
    # its own on a python-can bus (Message objects, canopen's receive thread and queue), not the
    # rig's SDO client, whose frames take a raw socket (`hilrig.wire.node.SocketSdoClient`).
    assert TABLE.board.recorder is not None
    index = TABLE.board.recorder.index_of(RecorderObject.DATA)
    ours = rig.node.block_upload(index, 0, "upload the recording again")
    bus = private_bus.open()
    network = canopen.Network(bus)
    try:
        network.connect()
        remote = canopen.RemoteNode(rig.node.node_id, str(EDS))
        network.add_node(remote)
        assert type(remote.sdo) is SdoClient
        remote.sdo.RESPONSE_TIMEOUT = 5.0  # a hang guard for the emulated VM
        with remote.sdo.open(index, 0, "rb", block_transfer=True) as stream:
            theirs = bytes(stream.read())
    finally:
        network.disconnect()  # shuts the bus down too
    assert len(ours) > 64_000 and theirs == ours


@pytest.mark.requirement("REC_02")
def test_a_channel_in_use_takes_another_field_but_not_none(node_under_test) -> None:
    # While a channel is in use (sub-index <= channels in use) it may be pointed at another
    # field, but not at none (0): a recording's channels all name a field, as a PDO mapping's.
    assert TABLE.board.recorder is not None
    channels = TABLE.board.recorder.index_of(RecorderObject.CHANNELS)
    sdo = node_under_test.node.sdo
    first, second = TABLE.entry("motor_velocity").index, TABLE.entry("joint_torque").index
    sdo.download(channels, 1, struct.pack("<H", first))
    sdo.download(channels, 0, bytes([1]))
    sdo.download(channels, 1, struct.pack("<H", second))
    assert struct.unpack("<H", sdo.upload(channels, 1))[0] == second, "the channel in use was re-pointed"
    with pytest.raises(canopen.SdoAbortedError) as refused:
        sdo.download(channels, 1, struct.pack("<H", 0))
    assert refused.value.code == SdoAbortCode.PARAMETER_INCOMPATIBLE
    assert struct.unpack("<H", sdo.upload(channels, 1))[0] == second, "a refused write changes nothing"
    sdo.download(channels, 2, struct.pack("<H", 0))  # not in use: none is fine there


EDGE_SAMPLES = 10


def triggered_at(rig, recorder: RecorderClient) -> int:
    """The rig cycle of a finished recording's trigger sample."""
    rig.run(cycles=EDGE_SAMPLES + 2)
    assert recorder.progress().state == "done", recorder.progress()
    recording = recorder.upload()
    return recording.cycle_of(recording.trigger_sample) - 1  # the firmware counts SYNCs from 1


@pytest.mark.requirement("REC_01")
def test_a_trigger_fires_on_a_crossing_of_its_edge_only(make_scenario) -> None:
    """A rising level trigger armed above its level waits for the value to go below and come back
    to the level; a falling flag trigger fires when a watched bit clears, not while the bits stay
    set nor when an unwatched one clears (the REAL32 setpoint carries the bits, as a bitset field
    would). Each recording's trigger sample is the cycle of the crossing."""
    rig = make_scenario().rig
    rig.set("control_mode", ControlMode.VELOCITY)
    rig.set("velocity_setpoint", 2.0)
    recorder = RecorderClient(rig.node, TABLE)
    watch = {"channels": ("motor_velocity",), "samples": EDGE_SAMPLES, "trigger_field": "velocity_setpoint"}

    recorder.configure(CaptureSettings(**watch, trigger="level", level=1.0, edge="rising"))
    recorder.arm()
    rig.run(cycles=20)
    assert recorder.progress().state == "armed", "above its level from the start: no crossing yet"
    rig.set("velocity_setpoint", 0.5)
    rig.run(cycles=20)
    assert recorder.progress().state == "armed", "going below its level is not a rising edge"
    crossing = rig.cycle
    rig.set("velocity_setpoint", 1.0)  # at the level: a rising edge
    assert triggered_at(rig, recorder) == crossing

    rig.set("velocity_setpoint", 3.0)  # bits 0 and 1
    recorder.configure(CaptureSettings(**watch, trigger="flag", mask=0b01, edge="falling"))
    recorder.arm()
    rig.run(cycles=20)
    assert recorder.progress().state == "armed", "the watched bit stays set: no falling edge"
    rig.set("velocity_setpoint", 1.0)  # bit 1 clears: not watched
    rig.run(cycles=20)
    assert recorder.progress().state == "armed", "an unwatched bit cleared"
    crossing = rig.cycle
    rig.set("velocity_setpoint", 0.0)  # bit 0 clears
    assert triggered_at(rig, recorder) == crossing
