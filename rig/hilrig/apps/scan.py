"""Which CANopen nodes are on a bus (`hilrig scan`).

Two ways to be found, run together: a node's boot-up or heartbeat (on its `heartbeat_cob_id`) heard
while listening, and an answer to an SDO upload of 0x1018 sub 1 (vendor id), sent to node ids
1..127 at once at the start (`listen`). Each node found is then asked for 0x1008 (device name)
and 0x1018 (product code, revision) with a short timeout (`identify`); what a node lacks stays
None.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import can
import canopen
from canopen.sdo import SdoAbortedError, SdoCommunicationError

from boardproto.cia301 import (
    HEARTBEAT_STATE_MASK,
    FunctionCode,
    SdoCommand,
    function_of,
    sdo_request_cob_id,
)

IDENTITY_INDEX = 0x1018
DEVICE_NAME_INDEX = 0x1008
SEND_RETRY_S = 0.002


@dataclass
class FoundNode:
    node_id: int
    state: int | None = None  # heartbeat state byte
    answered_sdo: bool = False
    vendor_id: int | None = None
    product_code: int | None = None
    revision: int | None = None
    device_name: str | None = None


def probe_frame(node_id: int) -> can.Message:
    request = SdoCommand.INITIATE_UPLOAD_REQUEST
    data = bytes([request, IDENTITY_INDEX & 0xFF, IDENTITY_INDEX >> 8, 1, 0, 0, 0, 0])
    return can.Message(arbitration_id=sdo_request_cob_id(node_id), data=data, is_extended_id=False)


def _send(bus: can.BusABC, message: can.Message, deadline: float) -> None:
    """Send, retrying while the adapter's transmit queue is full (127 frames at once)."""
    while True:
        try:
            bus.send(message, timeout=max(0.0, deadline - time.monotonic()))
            return
        except can.CanOperationError:
            if time.monotonic() >= deadline:
                raise
            threading.Event().wait(SEND_RETRY_S)


def listen(bus: can.BusABC, listen_s: float, ids: range, *, probe: bool) -> dict[int, FoundNode]:
    """Send the SDO probes (if `probe`), then collect heartbeats and answers for `listen_s`."""
    found: dict[int, FoundNode] = {}
    deadline = time.monotonic() + listen_s
    for node_id in ids if probe else ():
        _send(bus, probe_frame(node_id), deadline)
    while (remaining := deadline - time.monotonic()) > 0:
        message = bus.recv(remaining)
        if message is None or message.is_extended_id or message.is_remote_frame:
            continue
        cob_id = message.arbitration_id
        function, node_id = function_of(cob_id)
        if node_id not in ids:
            continue
        if function == FunctionCode.HEARTBEAT and len(message.data) == 1:
            found.setdefault(node_id, FoundNode(node_id)).state = message.data[0] & HEARTBEAT_STATE_MASK
        elif function == FunctionCode.SDO_RESPONSE and len(message.data) == 8:
            data = bytes(message.data)
            if int.from_bytes(data[1:3], "little") != IDENTITY_INDEX or data[3] != 1:
                continue
            node = found.setdefault(node_id, FoundNode(node_id))
            node.answered_sdo = True
            if data[0] & 0xE3 == 0x43:  # expedited upload answer with size
                node.vendor_id = int.from_bytes(data[4:8], "little")
    return found


def identify(bus: can.BusABC, node: FoundNode, timeout_s: float) -> None:
    """Read device name, product code and revision (each may be missing)."""
    network = canopen.Network(bus)
    remote = canopen.RemoteNode(node.node_id, canopen.ObjectDictionary())
    remote.sdo.RESPONSE_TIMEOUT = timeout_s
    network.add_node(remote)
    network.connect()
    try:

        def upload(index: int, subindex: int) -> bytes | None:
            try:
                return remote.sdo.upload(index, subindex)
            except (SdoAbortedError, SdoCommunicationError):
                return None

        if node.vendor_id is None and (raw := upload(IDENTITY_INDEX, 1)) is not None:
            node.vendor_id = int.from_bytes(raw[:4], "little")
        if (raw := upload(IDENTITY_INDEX, 2)) is not None:
            node.product_code = int.from_bytes(raw[:4], "little")
        if (raw := upload(IDENTITY_INDEX, 3)) is not None:
            node.revision = int.from_bytes(raw[:4], "little")
        if (raw := upload(DEVICE_NAME_INDEX, 0)) is not None:
            node.device_name = raw.decode("latin-1").rstrip("\x00")
    finally:
        if network.notifier is not None:
            network.notifier.stop(1.0)
            network.notifier = None


__all__ = ["FoundNode", "identify", "listen", "probe_frame"]
