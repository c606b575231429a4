"""The `make run` demo. Runs inside tools/with-vcan (native vcan or the micro-VM).

Today: proves the bus path end to end. A second process answers frames on a private vcan0,
this process measures round trips, writes the bus traffic to a candump log with python-can's
own logger, and prints a summary. (The firmware + rig demo joint replaces the peer as the
firmware issues land.)

    python tools/run-demo.py --out out/demo
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import can

from hilrig.netns import PrivateBus

PEER = Path(__file__).resolve().parent.parent / "tests" / "bus_echo_peer.py"


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--out", type=Path, default=Path("out/demo"), help="output folder (default: out/demo)"
    )
    parser.add_argument("--frames", type=int, default=200, help="round trips to make (default: 200)")
    args = parser.parse_args()
    if args.frames <= 0:
        parser.error("--frames must be positive")
    args.out.mkdir(parents=True, exist_ok=True)
    log_path = args.out / "bus.log"

    # receive_own_messages: the candump log then holds both directions, from the bus itself.
    with PrivateBus() as private_bus, private_bus.open(receive_own_messages=True) as bus:
        logger = can.Logger(str(log_path))
        notifier = can.Notifier(bus, [logger])
        peer = private_bus.popen([sys.executable, str(PEER), private_bus.channel])
        round_trips: list[float] = []
        try:
            reader = can.BufferedReader()
            notifier.add_listener(reader)
            while (msg := reader.get_message(60.0)) is not None and msg.arbitration_id != 0x700:
                pass
            for n in range(args.frames):
                sent_at = time.perf_counter()
                bus.send(
                    can.Message(arbitration_id=0x123, data=n.to_bytes(4, "little"), is_extended_id=False)
                )
                while True:
                    msg = reader.get_message(10.0)
                    if msg is None:
                        print(f"demo: no answer to frame {n} within 10 s", file=sys.stderr)
                        return 1
                    if msg.arbitration_id == 0x124:
                        break
                round_trips.append(time.perf_counter() - sent_at)
                if (n + 1) % 50 == 0:
                    print(f"demo: {n + 1}/{args.frames} round trips", flush=True)
            bus.send(can.Message(arbitration_id=0x7FF, data=b"", is_extended_id=False))
            peer.wait(timeout=60)
        finally:
            if peer.poll() is None:
                peer.kill()
                peer.wait()
            notifier.stop()
            logger.stop()

    ms = sorted(rt * 1e3 for rt in round_trips)
    print()
    print(f"bus path          {os.environ.get('HIL_BUS_PATH', 'unknown')}")
    print(f"round trips       {len(ms)}")
    print(f"median            {statistics.median(ms):.3f} ms")
    print(f"95th percentile   {ms[int(0.95 * (len(ms) - 1))]:.3f} ms")
    print(f"bus log (candump) {log_path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
