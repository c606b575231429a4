"""A second process on the bus for the smoke test: answers every frame with ID 0x123 by a frame
with ID 0x124 carrying the same bytes reversed, and exits on ID 0x7FF.

Run as: python tests/bus_echo_peer.py CHANNEL
"""

import sys

import can

# Identifiers of no CANopen service (0x781..0x7FE is outside the predefined connection set),
# so this bus test cannot be mistaken for one; 0x7FF ends the peer.
READY_ID, ECHO_REQUEST_ID, ECHO_ANSWER_ID = 0x7F0, 0x7A3, 0x7A4


def main() -> int:
    channel = sys.argv[1]
    with can.Bus(interface="socketcan", channel=channel) as bus:
        bus.send(can.Message(arbitration_id=READY_ID, data=b"\x00", is_extended_id=False))  # ready
        while True:
            msg = bus.recv(timeout=60.0)
            if msg is None:
                print("echo peer: no frame for 60 s, giving up", file=sys.stderr)
                return 1
            if msg.arbitration_id == 0x7FF:
                return 0
            if msg.arbitration_id == ECHO_REQUEST_ID:
                bus.send(
                    can.Message(
                        arbitration_id=ECHO_ANSWER_ID, data=bytes(reversed(msg.data)), is_extended_id=False
                    )
                )


if __name__ == "__main__":
    sys.exit(main())
