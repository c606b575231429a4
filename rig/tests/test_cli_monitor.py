"""`hilrig monitor` on python-can's virtual bus: every CAN id one row, decoded with the board's
names (the DBC's PDOs, the CiA 301 services in words), error frames counted, nothing sent."""

from __future__ import annotations

import struct
import threading

import can
import pytest

from boardproto.cia301 import SYNC_COB_ID, NmtState, emcy_cob_id, heartbeat_cob_id, sdo_response_cob_id
from hilrig.cli import main
from hilrig.table import BOARD_TABLE

NODE = 0x10


SYNC, TPDO1 = SYNC_COB_ID, BOARD_TABLE.tpdo(1).cob_id(NODE)
EMCY, HEARTBEAT = emcy_cob_id(NODE), heartbeat_cob_id(NODE)
SDO_ANSWER = sdo_response_cob_id(NODE)
KP = next(field for field in BOARD_TABLE.fields if field.name == "velocity_kp")


def frames() -> list[can.Message]:
    return [
        can.Message(arbitration_id=SYNC, data=bytes([7]), is_extended_id=False),  # counter 7
        can.Message(arbitration_id=TPDO1, data=bytes(8), is_extended_id=False),
        # EMCY 0x8130 (heartbeat consumer), error register 0x11
        can.Message(arbitration_id=EMCY, data=bytes([0x30, 0x81, 0x11]) + bytes(5), is_extended_id=False),
        can.Message(arbitration_id=HEARTBEAT, data=bytes([NmtState.OPERATIONAL]), is_extended_id=False),
        # the board's answer to an upload of velocity_kp: 0.25, expedited
        can.Message(
            arbitration_id=SDO_ANSWER,
            data=struct.pack("<BHBf", 0x43, KP.index, 0, 0.25),
            is_extended_id=False,
        ),
        can.Message(is_error_frame=True),
    ]


def test_monitor_shows_each_id_decoded_with_the_boards_names(capsys: pytest.CaptureFixture[str]) -> None:
    channel = "monitor-test"
    done = threading.Event()
    heard: list[can.Message] = []

    def send() -> None:  # until the monitor is done: it counts whatever comes after it listens
        with can.Bus(interface="virtual", channel=channel, receive_own_messages=False) as bus:
            while not done.is_set():
                for message in frames():
                    bus.send(message)
                if (message := bus.recv(timeout=0.01)) is not None:
                    heard.append(message)

    sender = threading.Thread(target=send)
    sender.start()
    try:
        # Ten rounds of the six frames: the sender goes on until the monitor has counted them.
        code = main(["monitor", "-i", "virtual", "-c", channel, "--count", "60", "-n", "0x10"])
    finally:
        done.set()
        sender.join()
    out = capsys.readouterr().out.splitlines()
    assert code == 0
    assert out[0].startswith("monitor: virtual") and "error frames " in out[0]
    assert int(out[0].rsplit(" ", 1)[1]) > 0, out[0]
    by_id = {line.split()[0]: line for line in out[2:]}  # under the title and the header
    row = {can_id: by_id[f"0x{can_id:03X}"] for can_id in (SYNC, TPDO1, EMCY, HEARTBEAT, SDO_ANSWER)}
    assert len(by_id) == 5, out
    assert row[SYNC].endswith("SYNC 7")
    assert "TPDO1" in row[TPDO1] and "motor_duty=" in row[TPDO1]
    assert "0x8130 heartbeat_error" in row[EMCY]
    assert row[HEARTBEAT].endswith("heartbeat node 0x10 operational")
    assert row[SDO_ANSWER].endswith(
        f"SDO upload 0x{KP.index:04X}:00 velocity_kp=0.25 {KP.unit} from node 0x10 (expedited, 4 bytes)"
    )
    assert heard == [], "the monitor sent frames"
