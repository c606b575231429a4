"""Fault injection without a bus: the command-line syntax and its errors, then every fault kind
carried out by a Rig against the in-process fake node on python-can's virtual bus (whose law
echoes the encoder counters it received as motor_velocity/output_velocity, so what the node got
can be read back)."""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from dataclasses import dataclass

import can
import pytest

from boardproto.cia301 import SYNC_COB_ID
from hilrig.engine.rig import Rig
from hilrig.errors import FirmwareError
from hilrig.plants import JointParams
from hilrig.session.fake_node import FakeJointNode
from hilrig.session.faults import (
    DEFAULT_FLOOD_COB_ID,
    UNUSED_COB_ID,
    FaultInjector,
    FaultKind,
    FaultPlan,
    FaultSpec,
    FaultSpecError,
)
from hilrig.table import RigTable

TABLE = RigTable.load()
RPDO1 = TABLE.board.rpdo(1).cob_id(TABLE.board.node.default_node_id)  # the fake node's sensor RPDO
_channels = itertools.count()


# --- Syntax ------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (
            "drop:motor_encoder_counts@0.5+0.2",
            FaultSpec(FaultKind.DROP, 0.5, "motor_encoder_counts", None, 0.2),
        ),
        ("drop:rpdo2@1", FaultSpec(FaultKind.DROP, 1.0, "rpdo2")),
        ("delay:thermistor_adc=5@1+0.5", FaultSpec(FaultKind.DELAY, 1.0, "thermistor_adc", 5.0, 0.5)),
        ("offset:motor_current_adc=-300@0", FaultSpec(FaultKind.OFFSET, 0.0, "motor_current_adc", -300.0)),
        ("raw:thermistor_adc=0xFFFF@2", FaultSpec(FaultKind.RAW, 2.0, "thermistor_adc", 65535.0)),
        ("flood:0x7F0=2000@1+0.5", FaultSpec(FaultKind.FLOOD, 1.0, "0x7F0", 2000.0, 0.5)),
        ("malformed:length@1", FaultSpec(FaultKind.MALFORMED, 1.0, "length")),
        ("restart@2", FaultSpec(FaultKind.RESTART, 2.0)),
    ],
)
def test_fault_syntax_parses_and_prints_back(text: str, expected: FaultSpec) -> None:
    spec = FaultSpec.parse(text)
    assert spec == expected
    assert FaultSpec.parse(str(spec)) == spec


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("drop", "expected KIND[:TARGET][=VALUE]@START[+DURATION]"),
        ("shake:thermistor_adc@1", "unknown kind 'shake'; kinds: drop, delay, freeze"),
        ("freeze:thermistor@1", "unknown sensor 'thermistor'; sensors: motor_encoder_counts"),
        ("freeze@1", "name the sensor, e.g. freeze:thermistor_adc"),
        ("delay:thermistor_adc@1", "give the delay in cycles with =VALUE"),
        ("delay:thermistor_adc=0@1", "the delay must be at least 1 cycle"),
        ("offset:motor_current_adc=1.5@1", "offset needs a whole number, got 1.5"),
        ("raw:motor_current_adc=40000@1", "motor_current_adc travels as -32768..32767; 40000 cannot be sent"),
        ("kill@1+2", "kill happens once, at its start; drop the +DURATION"),
        ("malformed@1", "say which: malformed:length or malformed:cob-id"),
        ("flood=0@1", "the flood rate must be > 0 frames/s"),
        ("flood:0x000=10@1", "COB-ID 0x0 is outside 0x001..0x7FF"),
        ("drop:thermistor_adc@-1", "start must be a time >= 0 in seconds, got -1"),
        ("drop:thermistor_adc@1+0", "duration must be > 0, got 0"),
        ("freeze:thermistor_adc=3@1", "freeze takes no =VALUE"),
        ("drop:thermistor_adc@soon", "'soon' is not a number"),
    ],
)
def test_bad_fault_says_what_to_write(text: str, message: str) -> None:
    with pytest.raises(FaultSpecError, match=None) as raised:
        FaultSpec.parse(text)
    assert message in str(raised.value)


# --- Carried out by a rig ------------------------------------------------------------------
@dataclass
class Bench:
    rig: Rig
    fake: FakeJointNode
    spy: can.BusABC

    def frames(self) -> list[can.Message]:
        frames = []
        while (message := self.spy.recv(timeout=0)) is not None:
            frames.append(message)
        return frames

    def received(self, name: str) -> list[float]:
        return [float(v) for v in self.rig.history(name)[1]]


def _bench() -> Bench:
    channel = f"hilrig-faults-{next(_channels)}"
    rig_bus, fake_bus, spy = (can.Bus(interface="virtual", channel=channel) for _ in range(3))
    fake = FakeJointNode(fake_bus, table=TABLE)
    rig = Rig(
        rig_bus,
        table=TABLE,
        params=JointParams.fast_thermal(),
        seed=3,
        tpdo_timeout_s=0.5,
        activity=fake.activity,
    )
    fake.boot()
    rig.start()
    bench = Bench(rig, fake, spy)
    bench.frames()
    bench._buses = (rig_bus, fake_bus, spy)  # type: ignore[attr-defined]
    return bench


@pytest.fixture
def benches() -> Iterator[list[Bench]]:
    made: list[Bench] = []
    yield made
    for bench in made:
        bench.rig.close()
        bench.fake.close()
        for bus in bench._buses:  # type: ignore[attr-defined]
            bus.shutdown()


def _run(benches: list[Bench], faults: list[str], cycles: int = 12, **kwargs: object) -> Bench:
    bench = _bench()
    benches.append(bench)
    bench.rig.set("velocity_setpoint", 4.0)  # the plant moves, so encoder counts change
    injector = FaultInjector(bench.rig, FaultPlan.parse(faults), **kwargs)  # type: ignore[arg-type]
    injector.install()
    bench.rig.run(cycles=cycles)
    bench.injector = injector  # type: ignore[attr-defined]
    return bench


def test_delay_sends_each_value_n_cycles_late_then_catches_up(benches: list[Bench]) -> None:
    clean = _run(benches, [])
    delayed = _run(benches, ["delay:motor_encoder_counts=3@0.004+0.005"])
    truth = clean.received("motor_velocity")  # the fake echoes the counter it received
    got = delayed.received("motor_velocity")
    assert len(set(truth)) > 5, "the plant must move for this test to mean anything"
    expected = truth[:4] + truth[1:6] + truth[9:]
    assert got == expected


def test_freeze_holds_offset_wraps_and_raw_forces(benches: list[Bench]) -> None:
    clean = _run(benches, [])
    faulty = _run(
        benches,
        [
            "freeze:motor_encoder_counts@0.003+0.004",
            "offset:output_encoder_counts=-70000@0",  # more than a turn of the counter: wraps
            "raw:thermistor_adc=5000@0.005+0.001",
        ],
    )
    truth, got = clean.received("motor_velocity"), faulty.received("motor_velocity")
    assert got == truth[:3] + [truth[3]] * 4 + truth[7:]
    out_truth, out_got = clean.received("output_velocity"), faulty.received("output_velocity")
    assert out_got == [(v - 70000) % 65536 for v in out_truth]
    _, adc = faulty.rig.sent("thermistor_adc")
    assert list(adc[4:7]) == [adc[4], 5000, adc[6]] and adc[4] != 5000 and adc[6] != 5000


def test_drop_silences_the_sensor_frame_for_its_duration(benches: list[Bench]) -> None:
    bench = _bench()
    benches.append(bench)
    FaultInjector(bench.rig, FaultPlan.parse(["drop:thermistor_adc@0.002+0.003"])).install()
    bench.rig.run(cycles=8)
    per_cycle = _rpdo1_per_cycle(bench.frames())
    assert per_cycle == [1, 1, 0, 0, 0, 1, 1, 1]


def test_malformed_frames_and_flood_go_out_at_their_times(benches: list[Bench]) -> None:
    bench = _bench()
    benches.append(bench)
    injector = FaultInjector(
        bench.rig,
        FaultPlan.parse(["malformed:length@0.001", "malformed:cob-id@0.002", "flood=2500@0.003+0.004"]),
    )
    injector.install()
    bench.rig.run(cycles=10)
    frames = bench.frames()
    short = [m for m in frames if m.arbitration_id == RPDO1 and m.dlc != 8]
    assert [m.dlc for m in short] == [7]
    assert len([m for m in frames if m.arbitration_id == UNUSED_COB_ID]) == 1
    floods = [m for m in frames if m.arbitration_id == DEFAULT_FLOOD_COB_ID]
    assert len(floods) == 10  # 2.5 frames per 1 ms cycle for 4 cycles, paced exactly
    assert injector.frames_sent == {"malformed": 2, "flood": 10}
    assert [e.text.split(":")[0] for e in injector.log][:2] == ["malformed", "malformed"]
    assert injector.log[-1].text == "flood=2500@0.003+0.004: ended" and injector.log[-1].cycle == 7


def test_restart_reboots_the_node_and_the_rig_carries_on(benches: list[Bench]) -> None:
    bench = _bench()
    benches.append(bench)

    class FakeFirmware:  # what FaultInjector needs of hilrig.session.firmware.Firmware
        restarts = 0

        def kill(self) -> None:
            raise AssertionError("restart, not kill")

        def restart(self) -> None:
            FakeFirmware.restarts += 1
            bench.fake.boot()

    firmware = FakeFirmware()
    injector = FaultInjector(bench.rig, FaultPlan.parse(["restart@0.005"]), firmware=firmware)  # type: ignore[arg-type]
    injector.install()
    bench.rig.run(cycles=10)
    assert FakeFirmware.restarts == 1
    assert bench.rig.cycle == 10
    # The node counts SYNCs again from its new start: 5 before, 5 after.
    assert len(bench.fake.syncs) == 10
    assert [e.text for e in injector.log] == [
        "restart@0.005: firmware killed with SIGKILL, restarting",
        "restart@0.005: firmware booted again and is operational",
    ]


def test_kill_leaves_the_rig_to_report_the_dead_firmware(benches: list[Bench]) -> None:
    bench = _bench()
    benches.append(bench)
    killed: list[bool] = []

    class FakeFirmware:
        def kill(self) -> None:
            killed.append(True)
            bench.fake.close()  # silent from now on, as a killed process is

        def check(self) -> None:
            if killed:
                raise FirmwareError("joint-firmware (pid 1) was killed by SIGKILL")

    firmware = FakeFirmware()
    bench.rig.driver.liveness = firmware.check
    FaultInjector(bench.rig, FaultPlan.parse(["kill@0.003"]), firmware=firmware).install()  # type: ignore[arg-type]
    with pytest.raises(FirmwareError, match=r"cycle 3 \(t = 0.003 s\): .*killed by SIGKILL"):
        bench.rig.run(cycles=10)


def test_faults_that_need_what_the_rig_lacks_are_refused_at_install(benches: list[Bench]) -> None:
    bench = _bench()
    benches.append(bench)
    with pytest.raises(FaultSpecError, match="does not own the firmware process"):
        FaultInjector(bench.rig, FaultPlan.parse(["kill@1"])).install()
    with pytest.raises(FaultSpecError, match="no enabled RPDO4"):
        FaultInjector(bench.rig, FaultPlan.parse(["drop:rpdo4@1"])).install()


def _rpdo1_per_cycle(frames: list[can.Message]) -> list[int]:
    counts: list[int] = []
    pending = 0
    for message in frames:
        if message.arbitration_id == SYNC_COB_ID:
            counts.append(pending)
            pending = 0
        elif message.arbitration_id == RPDO1:
            pending += 1
    return counts


def test_plan_is_false_when_empty() -> None:
    assert not FaultPlan.parse([])
    assert FaultPlan.parse(["kill@1"])
