"""`hilrig monitor` on python-can's virtual bus: every CAN id one row, decoded with the board's
names (the DBC's PDOs, the CiA 301 services in words), error frames counted, nothing sent."""

from __future__ import annotations

import threading

import can
import pytest

from hilrig.cli import main

NODE = 0x10


def frames() -> list[can.Message]:
    return [
        can.Message(arbitration_id=0x080, data=bytes([7]), is_extended_id=False),  # SYNC, counter 7
        can.Message(arbitration_id=0x190, data=bytes(8), is_extended_id=False),  # TPDO1 of node 0x10
        # EMCY 0x8130 (heartbeat consumer) from node 0x10, error register 0x11
        can.Message(arbitration_id=0x090, data=bytes([0x30, 0x81, 0x11]) + bytes(5), is_extended_id=False),
        can.Message(arbitration_id=0x710, data=bytes([0x05]), is_extended_id=False),  # heartbeat: operational
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
        code = main(["monitor", "-i", "virtual", "-c", channel, "--duration", "1.5", "-n", "0x10"])
    finally:
        done.set()
        sender.join()
    out = capsys.readouterr().out.splitlines()
    assert code == 0
    assert out[0].startswith("monitor: virtual") and "error frames " in out[0]
    assert int(out[0].rsplit(" ", 1)[1]) > 0, out[0]
    by_id = {line.split()[0]: line for line in out[2:]}  # under the title and the header
    assert set(by_id) == {"0x080", "0x090", "0x190", "0x710"}, out
    assert by_id["0x080"].endswith("SYNC 7")
    assert "TPDO1" in by_id["0x190"] and "motor_duty=" in by_id["0x190"]
    assert "0x8130 heartbeat_error" in by_id["0x090"]
    assert by_id["0x710"].endswith("heartbeat node 0x10 operational")
    assert heard == [], "the monitor sent frames"
