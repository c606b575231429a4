"""A second process on the bus for the smoke test: answers every frame with ID 0x123 by a frame
with ID 0x124 carrying the same bytes reversed, and exits on ID 0x7FF.

Run as: python tests/bus_echo_peer.py CHANNEL
"""

import sys

import can


def main() -> int:
    channel = sys.argv[1]
    with can.Bus(interface="socketcan", channel=channel) as bus:
        bus.send(can.Message(arbitration_id=0x700, data=b"\x00", is_extended_id=False))  # ready
        while True:
            msg = bus.recv(timeout=60.0)
            if msg is None:
                print("echo peer: no frame for 60 s, giving up", file=sys.stderr)
                return 1
            if msg.arbitration_id == 0x7FF:
                return 0
            if msg.arbitration_id == 0x123:
                bus.send(
                    can.Message(arbitration_id=0x124, data=bytes(reversed(msg.data)), is_extended_id=False)
                )


if __name__ == "__main__":
    sys.exit(main())
