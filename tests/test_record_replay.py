"""Record and replay: the bus log of a faulted lockstep run, replayed as the master side
(`hilrig replay --as-master`) into a fresh firmware on the same bus, makes the firmware say the
same things frame for frame: identical decoded fields in every TPDO, identical EMCY and SDO
answers. What a team does to reproduce a field failure from a customer's log."""

from __future__ import annotations

import threading
from pathlib import Path

import can
import cantools
import pytest
from conftest import BOOT_TIMEOUT_S, FULL_MAPPING_ON_THE_IDEAL_BUS, NODE_ID, REPO, run_hilrig

from boardproto.cia301 import emcy_cob_id, heartbeat_cob_id
from hilrig.session.buslog import BusRecorder, node_cob_ids
from hilrig.session.faults import FaultInjector, FaultPlan
from hilrig.session.firmware import Firmware
from hilrig.session.netns import PrivateBus
from hilrig.table import ControlMode, RigTable

pytestmark = [pytest.mark.bus, FULL_MAPPING_ON_THE_IDEAL_BUS]

DBC = REPO / "build" / "protocol" / "board.dbc"
TABLE = RigTable.load()
HEARTBEAT_ID = heartbeat_cob_id(NODE_ID)
REPLAY_TIMEOUT_S = 600  # hang guard for the software-emulated VM, not a timing check
# Faults in the recorded run, so the replay has to reproduce more than a quiet loop.
FAULTS = [
    "offset:motor_current_adc=400@0.05+0.05",
    "delay:output_encoder_counts=4@0.1+0.05",
    "malformed:length@0.12",
    "malformed:cob-id@0.13",
    "flood=4000@0.14+0.01",
]


def node_frames(log: Path) -> list[can.Message]:
    """What the node sent, in order, without heartbeats (those follow the wall clock)."""
    own = node_cob_ids(TABLE, NODE_ID) - {HEARTBEAT_ID}
    return [m for m in can.LogReader(str(log)) if m.arbitration_id in own]


def decoded_tpdos(frames: list[can.Message], dbc: cantools.database.can.Database) -> list[tuple[str, dict]]:
    tpdo_ids = {pdo.cob_id(NODE_ID) for pdo in TABLE.board.tpdos if pdo.enabled}
    return [
        (dbc.get_message_by_frame_id(m.arbitration_id).name, dbc.decode_message(m.arbitration_id, m.data))
        for m in frames
        if m.arbitration_id in tpdo_ids
    ]


@pytest.mark.requirement("RIG_03")
def test_a_recorded_run_replays_into_a_fresh_firmware_with_identical_decoded_fields(
    make_scenario, private_bus: PrivateBus, scenario_dir: Path
) -> None:
    first = make_scenario(seed=5, trace=False, subdir="recorded")
    FaultInjector(first.rig, FaultPlan.parse(FAULTS), firmware=first.firmware).install()
    first.rig.set("control_mode", ControlMode.VELOCITY)
    first.rig.set("velocity_setpoint", 2.0)
    first.rig.run(seconds=0.2)
    cycles = first.rig.cycle
    first.close()  # firmware stopped, bus log whole
    recorded = node_frames(first.bus_log)
    # The same log in words: the rig's SDO transfers by the objects' names, with their values.
    decoded = run_hilrig(private_bus, "replay", str(first.bus_log), "--decode")
    assert decoded.returncode == 0, decoded.stderr
    vendor = TABLE.board.node.vendor_id
    identity = (
        f"SDO upload 0x1018:01 Identity object.Vendor-ID={vendor} (0x{vendor:08X}) from node 0x{NODE_ID:02X} "
        "(expedited, 4 bytes)"
    )
    assert any(line.endswith(f"  {identity}") for line in decoded.stdout.splitlines()), (
        f"no {identity!r} in `hilrig replay {first.bus_log} --decode`"
    )

    # The second run: a fresh firmware on the same bus and no rig; the log's master side drives it.
    second_dir = scenario_dir / "replayed"
    recorder = BusRecorder(private_bus.open(), second_dir / "bus.log")
    watcher = private_bus.open()
    booted = threading.Event()
    notifier = can.Notifier(
        watcher,
        [lambda m: booted.set() if m.arbitration_id == HEARTBEAT_ID and bytes(m.data) == b"\x00" else None],
    )
    firmware = Firmware(private_bus, node_id=NODE_ID, log_path=second_dir / "firmware.log")
    try:
        firmware.start()
        if not booted.wait(BOOT_TIMEOUT_S):
            firmware.check()
            pytest.fail(f"no boot-up within {BOOT_TIMEOUT_S} s; {firmware.log_path}")
        replay = run_hilrig(
            private_bus, "replay", str(first.bus_log), "--as-master", timeout_s=REPLAY_TIMEOUT_S
        )
        assert replay.returncode == 0, replay.stderr
        firmware.check()
    finally:
        firmware.stop()  # SIGTERM: the frames of the last SYNC are out before it exits
        notifier.stop()
        watcher.shutdown()
        recorder.close()
    replayed = node_frames(second_dir / "bus.log")

    dbc = cantools.database.load_file(str(DBC))
    first_tpdos, second_tpdos = decoded_tpdos(recorded, dbc), decoded_tpdos(replayed, dbc)
    assert sum(name == "TPDO1" for name, _ in first_tpdos) == cycles, "the recorded run: one TPDO1 per SYNC"
    assert len(first_tpdos) > 7 * cycles
    for n, (want, got) in enumerate(zip(first_tpdos, second_tpdos, strict=False)):
        assert got == want, (
            f"TPDO {n} of {len(first_tpdos)} differs: recorded {want}, replayed {got}; "
            f"logs: {first.bus_log}, {second_dir / 'bus.log'}"
        )
    assert len(second_tpdos) == len(first_tpdos)
    # Everything else the node said (EMCY for the malformed frame, SDO answers) is the same too.
    assert [(m.arbitration_id, bytes(m.data)) for m in replayed] == [
        (m.arbitration_id, bytes(m.data)) for m in recorded
    ]
    emcy = [m for m in recorded if m.arbitration_id == emcy_cob_id(NODE_ID)]
    assert emcy, f"expected the malformed frame's EMCY in {first.bus_log}"
    print(
        f"\nreplayed {len(first_tpdos)} TPDOs of {cycles} cycles, {len(recorded)} node frames "
        f"({len(emcy)} EMCY): identical; {replay.stderr.strip().splitlines()[-1]}"
    )
