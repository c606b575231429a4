"""The timed bus (`hilrig.wire.bustime`) on its own, and the lockstep driver on it against the
in-process fake node (`hilrig.engine.bustiming`): arbitration order, what waits, what the node
and the plant get late."""

from __future__ import annotations

import itertools
from collections.abc import Iterator

import can
import pytest

from boardproto.cia301 import SYNC_COB_ID, sdo_request_cob_id
from hilrig.engine.rig import Rig
from hilrig.plants import JointParams
from hilrig.session.fake_node import FakeJointNode
from hilrig.table import BOARD_TABLE, RigTable
from hilrig.wire.bustime import WORST_CASE_BITS, BusFrame, TimedBus, needed_bitrate
from hilrig.wire.framebits import frame_bits_worst_case

NODE_ID = BOARD_TABLE.node.default_node_id
_channels = itertools.count()


def frames(cycle: int, *spec: tuple[int, int]) -> list[BusFrame]:
    return [BusFrame(cob_id, dlc, cycle) for cob_id, dlc in spec]


# The demo node's identifiers, lowest (highest priority) first: SYNC, TPDO1, RPDO1, TPDO2, ...
SYNC = SYNC_COB_ID
T1, T2, T3, T4, T8 = (BOARD_TABLE.tpdo(n).cob_id(NODE_ID) for n in (1, 2, 3, 4, 8))
R1, R2 = (BOARD_TABLE.rpdo(n).cob_id(NODE_ID) for n in (1, 2))
EIGHT_BYTES = frame_bits_worst_case(8)


def test_a_cycle_that_fits_carries_every_frame_in_arbitration_order() -> None:
    bus = TimedBus(1_000_000, 1000)  # 1000 bits per cycle
    w = bus.window(0, frames(0, (T2, 8), (SYNC, 1), (T1, 5)))
    assert [f.cob_id for f in w.delivered] == [SYNC, T1, T2]
    assert w.backlog == () and not w.late()
    assert w.busy_bits == frame_bits_worst_case(1) + frame_bits_worst_case(5) + EIGHT_BYTES


def test_what_does_not_start_in_time_waits_and_goes_first_by_its_identifier() -> None:
    bus = TimedBus(500_000, 1000)  # 500 bits: three 8-byte frames (405 bits) and a fourth starts
    eight = [(T1, 8), (T2, 8), (T3, 8), (T4, 8), (T8, 8)]
    w0 = bus.window(0, frames(0, *eight))
    assert [f.cob_id for f in w0.delivered] == [T1, T2, T3, T4]  # T4 starts at 405
    assert [f.cob_id for f in w0.backlog] == [T8]
    assert w0.load == 1.0 and bus.overhang == 4 * EIGHT_BYTES - 500
    w1 = bus.window(1, frames(1, *eight))
    # T8 of cycle 0 waits behind cycle 1's lower identifiers: after the 40-bit overhang, T4
    # starts at 445 again, and T8 starves.
    assert [(f.cob_id, f.origin) for f in w1.delivered] == [(T1, 1), (T2, 1), (T3, 1), (T4, 1)]
    assert [(f.cob_id, f.origin) for f in w1.backlog] == [(T8, 1)]
    assert [(f.cob_id, f.origin) for f in w1.replaced] == [(T8, 0)], "the newer replaced it"


def test_a_frame_late_by_a_cycle_says_so() -> None:
    bus = TimedBus(1_000_000, 1000)
    ids = [T1 + i for i in range(9)]
    bus.window(0, frames(0, *[(i, 8) for i in ids]))  # the 9th starts at 8 * 135 = 1080
    w = bus.window(1, frames(1, (T2, 8)))
    assert [(f.cob_id, f.origin) for f in w.delivered] == [(ids[-1], 0), (T2, 1)]
    assert [(f.cob_id, late) for f, late in w.late()] == [(ids[-1], 1)]
    assert bus.window(2, frames(2, (ids[-1], 8))).late() == []


def test_the_same_frames_give_the_same_schedule() -> None:
    def run() -> list[tuple[int, int, int]]:
        bus = TimedBus(250_000, 1000)
        out = []
        for n in range(20):
            w = bus.window(n, frames(n, (SYNC, 1), (T1, 5), (R1, 8), (T2, 8), (R2, 8)))
            out += [(n, f.cob_id, f.origin) for f in w.delivered]
        return out

    assert run() == run()


def test_a_cycle_that_fits_with_nothing_waiting_is_the_steady_shortcut() -> None:
    bus = TimedBus(1_000_000, 1000)
    assert bus.bits_if_all_fit(((SYNC, 1), (T1, 5), (R1, 8))) == sum(WORST_CASE_BITS[n] for n in (1, 5, 8))
    assert bus.bits_if_all_fit(tuple((T1 + i, 8) for i in range(8))) is None
    assert bus.bits_if_all_fit(((T1, 5), (T1, 5))) is None  # one identifier twice: one of them waits
    assert bus.fits_cached("steady", lambda: [(SYNC, 1)]) == WORST_CASE_BITS[1]
    assert bus.fits_cached("steady", lambda: []) == WORST_CASE_BITS[1], "remembered by its shape"
    bus.window(0, frames(0, *[(T1 + i, 8) for i in range(9)]))  # one waits now
    assert bus.fits_cached("steady", lambda: [(SYNC, 1)]) is None


def test_needed_bitrate_is_the_lowest_that_carries_every_cycle() -> None:
    cycle = [(SYNC, 1), *[(T1 + i, 8) for i in range(5)]]  # 65 + 5 * 135 = 740 bits
    needed, late = needed_bitrate([cycle] * 5, 1000)
    assert needed == 1_000_000 and late[1_000_000] == 0
    assert late[125_000] > late[250_000] > late[500_000] > 0
    assert needed_bitrate([cycle * 2] * 5, 1000)[0] is None  # one identifier twice a cycle never fits


# --- The lockstep driver on the timed bus, against the fake node ---------------------------
@pytest.fixture
def bench(request: pytest.FixtureRequest) -> Iterator[tuple[Rig, can.BusABC]]:
    channel = f"hilrig-bustime-{next(_channels)}"
    rig_bus, fake_bus, spy = (can.Bus(interface="virtual", channel=channel) for _ in range(3))
    table = RigTable.load()
    fake = FakeJointNode(fake_bus, table=table)
    rig = Rig(
        rig_bus,
        table=table,
        params=JointParams(),
        seed=3,
        tpdo_timeout_s=0.5,
        activity=fake.activity,
        bitrate=request.param,
    )
    fake.boot()
    rig.start()
    request.node.fake_node = fake  # a test that makes the node send an EMCY
    yield rig, spy
    rig.close()
    fake.close()
    for bus in (rig_bus, fake_bus, spy):
        bus.shutdown()


@pytest.mark.parametrize("bench", [1_000_000], indirect=True)
def test_the_full_mapping_at_1_mbit_starves_the_lowest_priority_tpdos(bench: tuple[Rig, can.BusABC]) -> None:
    rig, _ = bench
    rig.set("velocity_setpoint", 2.0)
    rig.run(cycles=50)
    timeline = rig.bus_timeline
    assert timeline is not None and len(timeline.load) == 50
    assert max(timeline.load) == 1.0 and min(timeline.load) > 0.9, "a real bus is never over 100 %"
    by_cob = {pdo.cob_id: pdo for pdo in rig.node.tpdos.values() if pdo.enabled}
    tpdo4 = rig.node.tpdos[4]
    # The actuator TPDO (lowest identifier) is in every cycle; TPDO4 (0x490) is behind every
    # other every-SYNC frame and rarely gets through.
    duty_t, _ = rig.history("motor_duty")
    command_t, _ = rig.history("motor_duty_command")
    assert len(duty_t) == 50
    assert len(command_t) < 10, f"{len(command_t)} of 50 cycles carried TPDO4 (0x{tpdo4.cob_id:X})"
    assert all(f.cob_id in by_cob for f in timeline.late)
    assert timeline.peak_backlog >= 2
    assert "frames late" in timeline.describe(1_000_000)
    print(timeline.describe(1_000_000))


@pytest.mark.parametrize("bench", [125_000], indirect=True)
def test_an_rpdo_that_does_not_fit_reaches_the_node_late(bench: tuple[Rig, can.BusABC]) -> None:
    rig, spy = bench
    while spy.recv(timeout=0) is not None:
        pass
    rig.run(cycles=20)
    seen = []
    while (message := spy.recv(timeout=0)) is not None:
        seen.append(message.arbitration_id)
    setpoints = rig.driver.rpdo_of("velocity_setpoint")
    assert setpoints is not None
    stream_cob = rig.node.rpdos[setpoints].cob_id
    assert seen.count(SYNC_COB_ID) == 20, "the SYNC always goes out"
    # 125 bits a cycle: the SYNC and the actuator TPDO fill it; the setpoint stream waits.
    assert seen.count(stream_cob) < 20
    sent_t, _ = rig.sent("velocity_setpoint")
    assert len(sent_t) == seen.count(stream_cob), "the history has the RPDO in the cycle it went out"


def test_the_summary_counts_each_scenario_once_per_bus_and_says_why_it_idealised() -> None:
    from hilrig.wire.bustime import bitrate_text, bus_summary, ideal_label

    assert [bitrate_text(b) for b in (1_000_000, 500_000, 83_333)] == [
        "1 Mbit/s",
        "500 kbit/s",
        "83.333 kbit/s",
    ]
    lines = bus_summary(
        [
            ["1 Mbit/s", "1 Mbit/s"],
            ["500 kbit/s"],
            [ideal_label("the full mapping")],
            [ideal_label("a robot"), ideal_label("a robot")],
            [ideal_label("the full mapping"), "1 Mbit/s"],
        ]
    )
    assert lines == [
        "3 scenarios on the timed bus (1 Mbit/s 2, 500 kbit/s 1)",
        "3 scenarios on the ideal bus, which carries any load:",
        "    2 the full mapping",
        "    1 a robot",
    ]
    assert bus_summary([[], []]) == []


def test_queued_frames_all_go_in_turn_and_no_newer_one_replaces_them() -> None:
    # An SDO transfer's frames or EMCYs are a sequence, not a PDO's mailbox.
    bus = TimedBus(250_000, 1000)  # 250 bits: two 8-byte frames start
    sdo = sdo_request_cob_id(NODE_ID)
    first = [BusFrame(sdo, 8, 0, queued=True) for _ in range(3)]
    w0 = bus.window(0, first)
    assert w0.delivered == tuple(first[:2]) and w0.backlog == (first[2],)
    w1 = bus.window(1, [BusFrame(sdo, 8, 1, queued=True)])
    assert w1.replaced == () and [f.origin for f in w1.delivered] == [0, 1]


@pytest.mark.parametrize("bench", [2_000_000], indirect=True)
def test_an_sdo_answer_reaches_the_master_when_the_bus_carried_it(bench: tuple[Rig, can.BusABC]) -> None:
    # 2 Mbit/s carries the full mapping with room to spare: the request and the answer go in
    # the next cycle's time, after the cycle's PDOs, and the master has its answer after it.
    rig, _ = bench
    rig.run(cycles=5)
    timing = rig.driver.bus_timing
    assert timing is not None
    steady = timing.timeline.load[-1]
    rig.read("velocity_kp")
    assert rig.cycle == 6, "one cycle ran for the bus to carry the transfer"
    assert timing.sdo_waiting == 0 and timing.sdo_delivered == 2
    sdo_bits = 2 * WORST_CASE_BITS[8]
    assert timing.timeline.load[-1] * timing.bus.window_bits == pytest.approx(steady * 2000 + sdo_bits)
    rig.run(cycles=1)
    assert timing.timeline.load[-1] == pytest.approx(steady), "and the next cycle is steady again"


@pytest.mark.parametrize("bench", [1_000_000], indirect=True)
def test_an_sdo_the_overloaded_bus_never_carries_times_out_for_the_master(
    bench: tuple[Rig, can.BusABC],
) -> None:
    # At 1 Mbit/s the full mapping's every-SYNC PDOs fill each cycle: the SDO channel's
    # identifiers (0x590, 0x610: after every PDO's) never win arbitration.
    from hilrig.engine.bustiming import SDO_ANSWER_TIMEOUT_S
    from hilrig.errors import SdoTimeoutError

    rig, _ = bench
    rig.run(cycles=2)
    with pytest.raises(SdoTimeoutError, match="carried no frame of the SDO transfer"):
        rig.read("velocity_kp")
    assert rig.cycle == 2 + round(SDO_ANSWER_TIMEOUT_S * 1000)
    timing = rig.driver.bus_timing
    assert timing is not None and timing.sdo_waiting == 0 and timing.sdo_delivered == 0
    assert not any(f.payload == "sdo" for f in timing.bus.backlog), "the abandoned frames left the bus"


@pytest.mark.parametrize("bench", [2_000_000], indirect=True)
def test_an_emcy_takes_bus_time_in_its_turn(
    bench: tuple[Rig, can.BusABC], request: pytest.FixtureRequest
) -> None:
    rig, _ = bench
    rig.run(cycles=3)
    timing = rig.driver.bus_timing
    assert timing is not None
    window = timing.bus.window_bits
    steady = timing.timeline.load[-1] * window
    request.node.fake_node.send_emcy(0x1000, 1)
    rig.run(cycles=3)
    assert rig.emcy, "the rig has the EMCY"
    # It came in one of the next cycles' exchanges (or between them) and took the time of the
    # one after: once, in one of these three windows, beside the steady cycle's frames.
    loads = [load * window for load in timing.timeline.load[-3:]]
    assert sum(loads) == pytest.approx(3 * steady + WORST_CASE_BITS[8])
    assert sorted(loads)[:2] == pytest.approx([steady, steady])
