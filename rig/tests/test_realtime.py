"""The real-time driver and the scenario API in real time, against the in-process fake node on
python-can's virtual bus. Time comes from a clock the test owns (its `wait` advances it by the
deadline plus a scripted lateness), so every tick time and every dt is known exactly; no
assertion depends on how fast the machine is."""

from __future__ import annotations

import itertools
import threading
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import can
import pytest

from boardproto.cia301 import SYNC_COB_ID, sync_counter
from hilrig.engine.realtime import RealTimeDriver, SyncProducer, WallHistory
from hilrig.engine.rig import Rig
from hilrig.errors import NoValueError, RealTimeError
from hilrig.plants import JointParams
from hilrig.session.fake_node import DUTY_PER_VELOCITY_SETPOINT, FakeJointNode
from hilrig.table import BOARD_TABLE, RigTable

PERIOD_US = 10_000
PERIOD_S = PERIOD_US / 1e6
NODE_ID = BOARD_TABLE.node.default_node_id  # the fake node's, 0x10
RPDO1_ID, RPDO2_ID = (BOARD_TABLE.rpdo(n).cob_id(NODE_ID) for n in (1, 2))  # sensors, setpoint stream
_channels = itertools.count()


class FakeClock:
    """Seconds that move only when the driver waits: by the time asked, plus the next of
    `lateness` (how late the 'operating system' wakes the rig up)."""

    def __init__(self, lateness: Iterable[float] = ()) -> None:
        self.now = 1000.0
        self.lateness = iter(lateness)
        self.waits: list[float] = []

    def __call__(self) -> float:
        return self.now

    def wait(self, seconds: float) -> None:
        self.waits.append(seconds)
        self.now += seconds + next(self.lateness, 0.0)


@dataclass
class Bench:
    rig: Rig
    fake: FakeJointNode
    spy: can.BusABC
    clock: FakeClock | None

    @property
    def driver(self) -> RealTimeDriver:
        assert isinstance(self.rig.driver, RealTimeDriver)
        return self.rig.driver

    def frame_ids(self) -> list[int]:
        ids = []
        while (message := self.spy.recv(timeout=0)) is not None:
            ids.append(message.arbitration_id)
        return ids


@pytest.fixture(scope="session")
def table() -> RigTable:
    return RigTable.load()


def _bench(table: RigTable, *, physics: bool = True, clock: FakeClock | None = None) -> Iterator[Bench]:
    channel = f"hilrig-rt-{next(_channels)}"
    rig_bus, fake_bus, spy = (can.Bus(interface="virtual", channel=channel) for _ in range(3))
    fake = FakeJointNode(fake_bus, table=table)
    rig = Rig(
        rig_bus, table=table, params=JointParams(), mode="realtime", physics=physics, period_us=PERIOD_US
    )
    if clock is not None:
        rig.driver.clock, rig.driver.wait = clock, clock.wait  # type: ignore[attr-defined]
    fake.boot()
    rig.start()
    bench = Bench(rig, fake, spy, clock)
    bench.frame_ids()  # start-up traffic is not what the tests look at
    yield bench
    rig.close()
    fake.close()
    for bus in (rig_bus, fake_bus, spy):
        bus.shutdown()


@pytest.fixture
def late_bench(table: RigTable) -> Iterator[Bench]:
    # Tick 1 wakes 3 ms late, tick 3 wakes 22.5 ms late (two whole ticks missed).
    yield from _bench(table, clock=FakeClock([0.003, 0.0, 0.0225]))


@pytest.fixture
def bench(table: RigTable) -> Iterator[Bench]:
    yield from _bench(table, clock=FakeClock())


def test_physics_is_stepped_by_the_measured_time_on_an_absolute_grid(
    late_bench: Bench, monkeypatch: pytest.MonkeyPatch
) -> None:
    steps: list[float] = []
    plant_step = late_bench.rig.plant.step

    def spy_step(dt_s: float) -> None:
        steps.append(dt_s)
        plant_step(dt_s)

    monkeypatch.setattr(late_bench.rig.plant, "step", spy_step)
    late_bench.rig.run(cycles=5)
    # Deadlines stay at 0, 10, 20, 30, ... ms: the late tick 1 does not shift tick 2, and the
    # ticks at 30 and 40 ms, missed entirely, are skipped (counted), not run back to back.
    assert late_bench.clock is not None
    assert late_bench.clock.waits == pytest.approx([0.010, 0.007, 0.010, 0.0075])
    assert steps == pytest.approx([0.013, 0.007, 0.0325, 0.0075])  # the first tick is t = 0
    assert late_bench.rig.overruns == 2
    assert late_bench.rig.t == pytest.approx(0.060)
    assert late_bench.rig.state.time_s == pytest.approx(0.060)
    assert late_bench.rig.physics_lost_s == 0.0


def test_a_rig_far_behind_cuts_the_plant_step_and_counts_the_loss(table: RigTable) -> None:
    # Tick 1 wakes 95 ms late: the plant steps 5 periods (50 ms) and 55 ms are counted lost,
    # rather than a long step making the next tick later still.
    for bench in _bench(table, clock=FakeClock([0.095])):
        bench.rig.run(cycles=3)
        assert bench.rig.t == pytest.approx(0.110)
        assert bench.rig.state.time_s == pytest.approx(0.055)
        assert bench.rig.physics_lost_s == pytest.approx(0.055)


def test_history_is_on_the_wall_timeline(late_bench: Bench) -> None:
    late_bench.rig.set("velocity_setpoint", 1.0)
    late_bench.rig.run(cycles=5)
    ticks = [0.0, 0.013, 0.020, 0.0525, 0.060]
    t_sent, sent = late_bench.rig.sent("velocity_setpoint")
    assert list(t_sent) == pytest.approx(ticks)
    assert list(sent) == [1.0] * 5
    t_truth, _ = late_bench.rig.truth("load_velocity")
    assert list(t_truth) == pytest.approx(ticks)


def test_each_tick_sends_sensors_setpoints_then_sync(bench: Bench) -> None:
    bench.rig.run(cycles=4)
    ids = [i for i in bench.frame_ids() if i in (SYNC_COB_ID, RPDO1_ID, RPDO2_ID)]
    assert ids == [RPDO1_ID, RPDO2_ID, SYNC_COB_ID] * 4


def test_run_and_events_count_in_wall_seconds(bench: Bench) -> None:
    fired: list[tuple[int, float]] = []
    bench.rig.at(0.025, lambda rig: fired.append((rig.cycle, rig.t)))
    bench.rig.run(seconds=0.05)
    assert bench.rig.cycle == 6  # ticks at 0, 10, ..., 50 ms
    assert bench.rig.t == pytest.approx(0.05)
    assert fired == [(4, pytest.approx(0.03))]  # the first tick boundary at or after 25 ms


def test_without_physics_no_sensor_rpdo_goes_out_and_the_plant_stands_still(table: RigTable) -> None:
    for bench in _bench(table, physics=False, clock=FakeClock([0.004])):
        initial = bench.rig.state
        bench.rig.set("velocity_setpoint", 20.0)
        bench.rig.run(cycles=5)
        ids = bench.frame_ids()
        assert RPDO1_ID not in ids
        assert ids.count(RPDO2_ID) == 5
        assert ids.count(SYNC_COB_ID) == 5
        assert bench.rig.state == initial
        with pytest.raises(NoValueError, match="without physics"):
            bench.rig.truth("load_velocity")
        t, _ = bench.rig.sent("velocity_setpoint")
        assert list(t) == pytest.approx([0.0, 0.014, 0.020, 0.030, 0.040])


def test_takes_the_latest_tpdo_values_without_waiting_for_them(table: RigTable) -> None:
    # The wall clock this time: the fake node answers each SYNC from its receive thread, and the
    # rig reads the answer at the next tick. Nothing has arrived at the first tick.
    for bench in _bench(table):
        bench.rig.set("velocity_setpoint", 20.0)
        bench.rig.run_until(
            lambda rig: rig.driver.history.has_received("motor_duty"), within_s=30.0, what="a TPDO1"
        )
        t, duty = bench.rig.history("motor_duty")
        assert t[0] > 0.0
        assert set(duty) == {20 * DUTY_PER_VELOCITY_SETPOINT}
        assert bench.rig.field("motor_duty") == 20 * DUTY_PER_VELOCITY_SETPOINT
        bench.rig.run(cycles=1)
        _, applied = bench.rig.truth("applied_duty")
        assert applied[0] == 0.0  # no duty known yet: the bridge stays off
        assert applied[-1] == pytest.approx(20 * DUTY_PER_VELOCITY_SETPOINT / 10_000)


def test_a_silent_node_is_a_bounded_error(bench: Bench) -> None:
    bench.fake.drop = lambda sync_number, tpdo: True
    bench.driver.tpdo_timeout_s = 0.05
    with pytest.raises(RealTimeError, match=r"no TPDO from node 0x10 for 0\.06 s") as info:
        bench.rig.run(seconds=1.0)
    assert isinstance(info.value, TimeoutError)


def test_mode_and_physics_are_checked_when_the_rig_is_made(table: RigTable) -> None:
    bus = can.Bus(interface="virtual", channel=f"hilrig-rt-{next(_channels)}")
    try:
        with pytest.raises(ValueError, match="'real-time' is not a valid TimingMode"):
            Rig(bus, table=table, mode="real-time")
        with pytest.raises(ValueError, match="physics=False needs mode='realtime'"):
            Rig(bus, table=table, physics=False)
    finally:
        bus.shutdown()


def test_wall_history_gives_the_recorded_tick_times_of_any_cycles() -> None:
    history = WallHistory(50_000)
    ticks = [0.0, 0.021595240, 0.05, 0.083000017]
    for t in ticks:
        history.record_tick(t)
    assert history.times_of([2, 1, 3]).tolist() == [ticks[2], ticks[1], ticks[3]]
    assert history.times_of(range(4)).tolist() == ticks
    assert history.times_of([]).tolist() == []


# --- The SYNC producer of a board without a rig --------------------------------------------------
SYNC_PERIOD_S = 0.25  # a binary fraction: the fake clock's sums are exact


def _producer(
    clock: FakeClock, stop_after: int, fail_at: int | None = None
) -> tuple[SyncProducer, list[int]]:
    sent: list[int] = []

    def send(counter: int) -> None:
        if len(sent) + 1 == fail_at:
            raise OSError("No buffer space available")
        sent.append(counter)
        if len(sent) == stop_after:
            producer.stop()

    producer = SyncProducer(send, SYNC_PERIOD_S, clock=clock, wait=clock.wait)
    return producer, sent


def test_the_sync_producer_counts_1_to_240_and_wraps_on_its_period() -> None:
    clock = FakeClock()
    producer, sent = _producer(clock, stop_after=243)
    producer.run()
    assert sent == [*range(1, 241), 1, 2, 3]
    assert clock.waits == [SYNC_PERIOD_S] * 243  # the first SYNC one period after the start
    assert (producer.sent, producer.overruns, producer.error) == (243, 0, None)


def test_a_late_sync_producer_skips_the_ticks_that_passed_and_counts_them() -> None:
    # Woken 2.5 periods late before the second SYNC: ticks 2 and 3 passed, the grid stays.
    clock = FakeClock([0.0, 2.5 * SYNC_PERIOD_S])
    producer, sent = _producer(clock, stop_after=4)
    producer.run()
    assert sent == [1, 2, 3, 4]  # the counter counts the SYNCs that went out
    assert producer.overruns == 2
    assert clock.waits == [SYNC_PERIOD_S, SYNC_PERIOD_S, SYNC_PERIOD_S / 2, SYNC_PERIOD_S]


def test_a_failing_send_stops_the_sync_producer_with_its_error() -> None:
    clock = FakeClock()
    producer, sent = _producer(clock, stop_after=10, fail_at=3)
    producer.run()
    assert sent == [1, 2]
    assert isinstance(producer.error, OSError)
    assert producer.sent == 2


def test_the_sync_producer_sends_from_its_thread_until_the_context_ends() -> None:
    sent: list[int] = []
    three = threading.Event()

    def send(counter: int) -> None:
        sent.append(counter)
        if len(sent) == 3:
            three.set()

    with SyncProducer(send, 0.001) as producer:
        assert three.wait(10.0), "no three SYNCs from the producer's thread"
    count = len(sent)
    assert sent[:3] == [1, 2, 3]
    assert sent == [sync_counter(n) for n in range(count)]
    assert producer.sent == count and producer.error is None
