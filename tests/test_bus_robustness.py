"""The node on a hostile bus: a flood of frames it must ignore, and frames that break the CiA 301
rules. The control loop must not lose a cycle and the firmware must count what it threw away
(its stop line in firmware.log). Each test is a scenario on its own private bus, in lockstep.

The firmware's socket has a kernel acceptance filter (CAN_RAW_FILTER: only the COB-IDs the node
consumes), so a frame on a foreign COB-ID never reaches the node. The flood test turns it off
(--no-acceptance-filter): its point is how the node itself ignores a flood."""

from __future__ import annotations

import struct
import time
from pathlib import Path

import can
import pytest
from conftest import FULL_MAPPING_ON_THE_IDEAL_BUS, NODE_ID, REPO, start_node, stop_node, stop_summary

from boardproto import load_table
from boardproto.cia301 import (
    NMT_COB_ID,
    STANDARD_ID_MASK,
    SYNC_COB_ID,
    NmtCommand,
    NmtState,
    SdoAbortCode,
    SdoCommand,
    sdo_request_cob_id,
    sdo_response_cob_id,
)
from boardproto.table import ERROR_RESET_CODE
from hilrig.plants import JointParams
from hilrig.session.faults import FaultInjector, FaultPlan
from hilrig.session.netns import PrivateBus
from hilrig.table import ControlMode, EmcyCode

pytestmark = [pytest.mark.bus, FULL_MAPPING_ON_THE_IDEAL_BUS]

VELOCITY_MODE = ControlMode.VELOCITY
GEAR_RATIO = JointParams().gear_ratio
EMCY_PDO_LENGTH = EmcyCode.PDO_LENGTH_ERROR
TABLE = load_table(REPO / "protocol" / "board.toml")

FLOOD_COB_ID = 0x001
"""Highest priority on a real bus (it wins every arbitration, the worst case for the node's
own traffic) and restricted by CiA 301: no CANopen service uses it, so the node must ignore
every one of these frames."""

ACCEPT_ALL = "--no-acceptance-filter"
"""joint-firmware's option: its socket receives every frame, as a controller without a filter."""

FOREIGN_COB_ID = 0x7E0
"""No service of this node uses it: outside the node's acceptance filter."""
FOREIGN_FRAMES = 100


FLOOD_FRAMES_PER_CYCLE = 40
"""Flood frames the rig sends ahead of every SYNC, in lockstep (`FaultKind.FLOOD`, a rate in
simulation time): 40 times the node's own traffic of a cycle, and still far below its receive
queue, so whatever the host's load the node sees every one of them and must ignore every one.
A flood in wall time (a thread sending back to back) let a busy host decide the test: the node's
queue overflowed and dropped the SYNC itself, a lost cycle that was the host's, not the node's."""
FLOOD_CYCLES = 500


@pytest.mark.requirement("BUS_01")
@pytest.mark.slow
def test_flood_of_frames_to_ignore_costs_no_control_cycle(make_scenario) -> None:
    # The flood is for the node, with its acceptance filter off: with it, the kernel would drop
    # the flood before the node saw a frame, and this test is about the node's own ignoring (a
    # flood on a COB-ID it does accept, or a controller without a filter). The rig's sockets
    # receive only the node's own frames (kernel filters: its TPDOs and EMCY on the frame link,
    # SDO answers and heartbeat for canopen), so the flood costs the rig nothing.
    s = make_scenario(trace=False, extra_args=[ACCEPT_ALL])
    rate_hz = FLOOD_FRAMES_PER_CYCLE / s.rig.period_s
    faults = FaultInjector(s.rig, FaultPlan.parse([f"flood:0x{FLOOD_COB_ID:03X}={rate_hz:g}@0"]))
    faults.install()
    s.rig.set("control_mode", VELOCITY_MODE)
    s.rig.set("velocity_setpoint", 4.0)
    s.rig.run(cycles=FLOOD_CYCLES)  # a LockstepError here would be a lost cycle
    assert s.rig.cycle == FLOOD_CYCLES
    sent = faults.frames_sent["flood"]
    assert sent == FLOOD_FRAMES_PER_CYCLE * FLOOD_CYCLES
    for name in ("motor_duty", "motor_velocity", "fault_flags"):
        assert len(s.rig.history(name)[0]) == FLOOD_CYCLES, f"{name}: expected a TPDO in each cycle"
    s.expect.never("fault_flags", lambda v: v != 0, "a fault")
    s.expect.settles_within("motor_velocity", target=4.0 * GEAR_RATIO, tolerance=0.02, by_s=0.45)
    s.close()
    counters = stop_summary(s.firmware)
    assert counters["cycles"] == FLOOD_CYCLES, counters
    # Every flood frame reached the node (no receive overrun) and was ignored, one by one.
    assert counters["receive overruns"] == 0, counters
    assert counters["ignored"] == sent, f"expected all {sent} flood frames ignored, got {counters}"
    print(f"\nflood on 0x{FLOOD_COB_ID:03X}: {sent} frames over {FLOOD_CYCLES} cycles, none lost; {counters}")


@pytest.mark.requirement("BUS_01")
def test_malformed_frames_are_counted_and_ignored(make_scenario, private_bus: PrivateBus) -> None:
    s = make_scenario()
    s.rig.set("control_mode", VELOCITY_MODE)
    s.rig.set("velocity_setpoint", 2.0)
    s.rig.run(seconds=0.2)
    rpdo2 = s.rig.node.rpdos[2]  # velocity_setpoint, torque_setpoint: 8 bytes
    assert rpdo2.names == ("velocity_setpoint", "torque_setpoint")
    bad = [
        # SDO upload request of velocity_kp in 4 bytes (CiA 301: SDO frames carry 8)
        (sdo_request_cob_id(NODE_ID), bytes([SdoCommand.INITIATE_UPLOAD_REQUEST, 0x00, 0x25, 0x00])),
        (NMT_COB_ID, bytes([NmtCommand.STOP])),  # NMT "stop" without the node-id byte
        (SYNC_COB_ID, bytes([0x01, 0x00])),  # SYNC with 2 bytes (0 or 1 allowed): must run no cycle
        (rpdo2.cob_id, struct.pack("<f", 50.0)),  # RPDO2 with 4 of its 8 bytes
        # A COB-ID no service of this node uses: its acceptance filter drops them in the kernel.
        *[(FOREIGN_COB_ID, bytes([0xDE, 0xAD]))] * FOREIGN_FRAMES,
    ]
    injected_at = s.rig.t
    with private_bus.open() as raw:
        for cob_id, data in bad:
            raw.send(can.Message(arbitration_id=cob_id, data=data, is_extended_id=False))
    s.rig.run(seconds=0.3)

    length_errors = [r for r in s.rig.emcy if r.code == EMCY_PDO_LENGTH]
    rpdo2_communication = TABLE.rpdo(2).communication_index
    assert len(length_errors) == 1 and length_errors[0].object_index == rpdo2_communication, (
        f"expected one {EMCY_PDO_LENGTH!r} about 0x{rpdo2_communication:04X} (RPDO2), "
        f"got {[str(r) for r in s.rig.emcy]}"
    )
    assert any(r.code == ERROR_RESET_CODE and r.time_s >= length_errors[0].time_s for r in s.rig.emcy), (
        "expected an EMCY error reset once well-formed RPDO2 frames came again"
    )
    assert s.rig.read("velocity_setpoint") == pytest.approx(2.0), "the short RPDO2 changed velocity_setpoint"
    assert s.rig.read("control_mode") == VELOCITY_MODE
    s.expect.never("fault_flags", lambda v: v != 0, "a fault")
    s.expect.stays_within(
        "motor_velocity", 0.9 * 2.0 * GEAR_RATIO, 1.1 * 2.0 * GEAR_RATIO, after_s=injected_at
    )
    cycles = s.rig.cycle
    s.close()
    counters = stop_summary(s.firmware)
    assert counters["cycles"] == cycles, f"expected {cycles} cycles (the bad SYNC runs none), got {counters}"
    assert counters["malformed"] == 3, counters  # SDO, NMT, SYNC
    assert counters["RPDO length errors"] == 1, counters
    assert counters["SDO aborts"] == 0, counters  # a malformed request gets no answer at all
    # The malformed frames are on COB-IDs the node accepts, so its filter hid none of them (the
    # counts above). The foreign ones never reached it: without the filter each would count as
    # ignored (the flood test shows that path); with it, ignored holds only the node's own.
    assert counters["ignored"] < FOREIGN_FRAMES, counters
    print(f"\nmalformed frames: {counters}")


SDO_CLIENT_TIMEOUT_S = 30.0  # hang guard for the software-emulated VM, not a timing check
ABORT_TOGGLE_BIT = SdoAbortCode.TOGGLE_BIT_NOT_ALTERNATED
ABORT_COMMAND_SPECIFIER = SdoAbortCode.COMMAND_SPECIFIER_INVALID


class SdoProbe:
    """A second SDO client on its own socket, sending raw requests out of order and reading
    the node's raw answers (the rig's canopen client never sees a conversation it did not start
    as its own: it drops unexpected answers before its next request)."""

    def __init__(self, private_bus: PrivateBus) -> None:
        self.bus = private_bus.open()
        self.bus.set_filters([{"can_id": sdo_response_cob_id(NODE_ID), "can_mask": STANDARD_ID_MASK}])

    def ask(self, *request: int) -> bytes:
        self.bus.send(
            can.Message(
                arbitration_id=sdo_request_cob_id(NODE_ID),
                data=bytes(request).ljust(8, b"\0"),
                is_extended_id=False,
            )
        )
        answer = self.bus.recv(SDO_CLIENT_TIMEOUT_S)
        # python-can sets the kernel filter after binding the socket: a frame that came in
        # between (a heartbeat, seen once in a clean-clone run) can still be queued. Skip it.
        while answer is not None and answer.arbitration_id != sdo_response_cob_id(NODE_ID):
            answer = self.bus.recv(SDO_CLIENT_TIMEOUT_S)
        assert answer is not None, f"no SDO answer to {bytes(request).hex(' ')}"
        return bytes(answer.data)

    def close(self) -> None:
        self.bus.shutdown()


def abort_code(answer: bytes) -> int | None:
    return struct.unpack_from("<I", answer, 4)[0] if answer[0] == SdoCommand.ABORT else None


@pytest.mark.requirement("BUS_01")
def test_nmt_for_other_nodes_and_sdo_out_of_order_cost_no_cycle(
    make_scenario, private_bus: PrivateBus
) -> None:
    s = make_scenario(trace=False)
    s.rig.set("control_mode", VELOCITY_MODE)
    s.rig.set("velocity_setpoint", 2.0)
    s.rig.run(seconds=0.1)

    # NMT stop, pre-operational and both resets, addressed to other nodes: none is for this one.
    # A node that obeyed would stop its TPDOs (the lockstep rig raises at once) or boot again.
    for other in (0x01, NODE_ID - 1, NODE_ID + 1, 0x7F):
        for command in (
            NmtCommand.STOP,
            NmtCommand.ENTER_PRE_OPERATIONAL,
            NmtCommand.RESET_NODE,
            NmtCommand.RESET_COMMUNICATION,
        ):
            s.rig.send_frame(NMT_COB_ID, bytes([command, other]))
        s.rig.run(cycles=5)
    s.rig.run(seconds=0.1)
    # Heartbeats go out on the wall clock: the latest one heard may still be the boot-up when the
    # run was quick, so the check is the next heartbeat's state, not the last one's.
    heard = s.rig.node.remote.nmt.wait_for_heartbeat(timeout=3 * TABLE.node.heartbeat_ms / 1000)
    assert heard == NmtState.OPERATIONAL.name, f"expected OPERATIONAL, got {heard}"

    # SDO out of order, from another client, between two cycles (CiA 301 7.2.4.3).
    probe = SdoProbe(private_bus)
    try:
        segment_without_transfer = probe.ask(0x60)  # upload segment, no upload in progress
        initiate = probe.ask(0x40, 0x08, 0x10, 0x00)  # upload 0x1008 device name: segmented
        wrong_toggle = probe.ask(0x70)  # first segment with toggle 1 (must be 0)
        after_abort = probe.ask(0x60)  # the aborted transfer is over: no segment to give
    finally:
        probe.close()
    assert abort_code(segment_without_transfer) == ABORT_COMMAND_SPECIFIER, segment_without_transfer.hex(" ")
    assert initiate[0] & 0xE3 == 0x41, f"expected a segmented upload with its size, got {initiate.hex(' ')}"
    assert abort_code(wrong_toggle) == ABORT_TOGGLE_BIT, wrong_toggle.hex(" ")
    assert abort_code(after_abort) == ABORT_COMMAND_SPECIFIER, after_abort.hex(" ")
    assert s.rig.read("velocity_setpoint") == pytest.approx(2.0), "the rig's own SDO client still works"

    resumed_at = s.rig.t
    s.rig.run(seconds=0.2)
    s.expect.never("fault_flags", lambda v: v != 0, "a fault")
    s.expect.stays_within(
        "motor_velocity", 0.9 * 2.0 * GEAR_RATIO, 1.1 * 2.0 * GEAR_RATIO, after_s=resumed_at
    )
    cycles = s.rig.cycle
    s.close()
    counters = stop_summary(s.firmware)
    assert counters["cycles"] == cycles, f"expected {cycles} cycles, one per SYNC, got {counters}"
    assert counters["SDO aborts"] == 3, counters
    print(f"\nNMT to 4 other nodes x 4 commands ignored; SDO aborts {counters['SDO aborts']}; {counters}")


SYNC_BURSTS, SYNCS_PER_BURST = 100, 20


@pytest.mark.requirement("SYNC_01")
@pytest.mark.slow
def test_sync_flood_runs_exactly_one_cycle_per_sync(private_bus: PrivateBus, scenario_dir: Path) -> None:
    """SYNCs back to back, as fast as this sender goes, in bursts of 20 (a burst's TPDOs must fit
    the receiving sockets' queues, so the test's own listeners lose nothing); after each burst an
    SDO round trip is the barrier (the node handles frames in order). Every SYNC must run exactly
    one control cycle and send its TPDOs: nothing lost, nothing merged."""
    under_test = start_node(private_bus, scenario_dir)
    try:
        node = under_test.node
        node.sdo.RESPONSE_TIMEOUT = SDO_CLIENT_TIMEOUT_S
        node.sdo.MAX_RETRIES = 1  # canopen 2.4.1: 0 would retry forever
        node.nmt.state = "OPERATIONAL"
        # One socket sends everything, so the node receives it in this order.
        network = under_test.network
        started = time.monotonic()
        for _ in range(SYNC_BURSTS):
            for _ in range(SYNCS_PER_BURST):
                network.send_message(SYNC_COB_ID, b"")
            node.sdo.upload(0x1001, 0)  # error register: answered after the burst was handled
        elapsed = time.monotonic() - started
    finally:
        code = stop_node(under_test)
    assert code == 0
    counters = stop_summary(under_test.firmware)
    syncs = SYNC_BURSTS * SYNCS_PER_BURST
    tpdos = [p for p in TABLE.tpdos if p.enabled]
    expected_tpdos = sum(syncs // p.transmission_type for p in tpdos)
    assert counters["cycles"] == syncs, f"expected {syncs} cycles, got {counters}"
    assert counters["TPDOs sent"] == expected_tpdos, f"expected {expected_tpdos} TPDOs, got {counters}"
    assert counters["send failures"] == 0, counters
    print(
        f"\nSYNC flood: {syncs} SYNCs in {elapsed:.2f} s wall ({syncs / elapsed:.0f}/s, bursts of "
        f"{SYNCS_PER_BURST}); cycles {counters['cycles']}, TPDOs {counters['TPDOs sent']}"
    )
