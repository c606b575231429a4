"""`hilrig.session.buslog.BusRecorder` without a CAN bus: python-can's virtual bus."""

from __future__ import annotations

from pathlib import Path

import can
import pytest

from hilrig.session.buslog import BusRecorder


class _StalledNotifier:
    """A receive thread that has not got round to any frame yet (as one behind a fast sender);
    stop() stops the listeners that can be, as python-can's does."""

    def __init__(self, bus: can.BusABC, listeners: list, timeout: float = 1.0) -> None:
        self.listeners = listeners

    def stop(self, timeout: float = 5.0) -> None:
        for listener in self.listeners:
            if hasattr(listener, "stop"):
                listener.stop()


def test_close_logs_what_the_receive_thread_had_not_taken_yet(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(can, "Notifier", _StalledNotifier)
    path = tmp_path / "bus.log"
    sender = can.Bus(interface="virtual", channel="stalled")
    recorder = BusRecorder(can.Bus(interface="virtual", channel="stalled"), path)
    try:
        for k in range(50):
            sender.send(can.Message(arbitration_id=0x123 + k, data=bytes([k]), is_extended_id=False))
    finally:
        recorder.close()
        sender.shutdown()
    logged = [m.arbitration_id for m in can.LogReader(str(path))]
    assert logged == [0x123 + k for k in range(50)]
