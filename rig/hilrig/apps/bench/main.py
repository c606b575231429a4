"""`make bench`: every figure a ratio of two things measured side by side in one run.

    tools/bench.py native  --out build/bench      C++ parts, natively: fw_board_bench, callgrind
    tools/with-vcan -- tools/bench.py bus --out build/bench
                                                   bus parts, on a private vcan bus (root)
    tools/bench.py report  --out build/bench      one table, printed and written to report.json
    tools/bench.py baseline --out build/bench [--baseline COMMIT] [--remove]
                                                   the engine against a baseline commit's alone,
                                                   natively (make bench-baseline)

What is measured, and against what:

* Lockstep speed, all on the same engine and firmware build, each measurement with a fresh
  firmware process, rounds alternating, best of each: (a) the full `Rig` (physics, history,
  checks) in a HIL session (`hilrig.session.builder`), untraced; (b) the same with a Rerun trace to a
  file, run beside (a) in pairs, four a round, each kind first in half (`rig_pair_orders`); (c)
  the floor: the same RPDO frames + SYNC out and the same number of TPDO frames back over one
  raw socket with kernel filters (`hilrig.wire.transport`), a Python call per frame, no physics, no
  checks, no trace; (d) the engine's exchange alone: the same frames through the call the Rig
  makes each cycle (`transport.exchange`, in C on the raw socket), decoded, no physics, no
  history; (e) for comparison, that exchange through python-can's Bus. Goals: (a)/(c) >= 0.5
  (best of each), (b)/(a) >= 0.8 (the median of the pairs' ratios); (a)/(d) is the stricter
  figure (what physics, history and checks cost on top of the engine's own wire).
  Simulated-time speed-up = cycles per second x the control period (the table's).
* SDO latency: expedited upload (a REAL32 board parameter) from `canopen.RemoteNode` to the
  firmware, next to the same upload served by a `canopen.LocalNode` (same EDS, another node id)
  running in its own Python process on the same private bus. Requests alternate. Goal: the
  firmware at least 3x faster (median).
* Firmware cycle cost: fw_board_bench (Google Benchmark) ratios, and the instructions of one
  control cycle under callgrind (`fw_cycle_count`): the real demo joint, the benchmark's
  stand-ins on the core board, and the same stand-ins on the naive unordered_map board.
* Field recorder cost: the instructions of its end-of-cycle call under callgrind, armed with 8
  channels (a sample every cycle and a level trigger looked at, its dearest state) next to
  idle, and the armed cost as a share of the demo joint's cycle.
* The Rig's own lockstep cycle, natively and deterministically (`tools/rig_probe.py`: the Rig
  over a raw-socket pair whose peer answers each SYNC at once, no firmware, no bus): the main
  thread's instructions per cycle under callgrind next to the engine's exchange alone with the
  same frames, and the bytes the Rig keeps per cycle (tracemalloc) next to the data bytes the bus
  carried. The VM's rates move between runs; these do not, so a change to the
  per-cycle path shows here first.
* The engine against a baseline commit's (`baseline`; --baseline, make's BASELINE; by
  default the last commit before the rig's folders became its layers): that commit's own
  `tools/rig_probe.py rig` and `engine`, from its tree exported once into <out>/baseline/, counted
  under callgrind as the checkout's are. Goal: the checkout's instructions per cycle within 10 %
  of the baseline's (new/old <= 1.1), for each.
* Long runs stay viewable: one traced 60 s lockstep run at 1 kHz (60000 cycles) of the full
  `Rig` against the firmware, the session as in (b); its trace.rrd stays in <out>/long-trace/.
  Reported: the .rrd's size (and bytes per cycle), and, on the host, the time from asking
  headless Chromium (software WebGL) for the served web viewer to the first screenshot of the
  whole recording with the overview's plots drawn (`hilrig.observe.browser.time_to_first_frame`).
* Bus load: `hilrig.apps.busload` for the default PDO mapping at 1 kHz.
* Free-running timing: the firmware in `--mode free`, no SYNC on the bus. Over SDO the rig
  turns the TPDO carrying velocity_controller_output into an event-driven one (type 255,
  inhibit 0, no event timer) and makes that value change every cycle (velocity control with
  only an integral gain, staleness limits raised so no fault stops the controller); the
  firmware then sends it right after each cycle. The kernel's receive timestamps of those
  frames give the cycle periods; period error = interval - period.

A measurement that fails (a probe that times out under callgrind on a busy host, exits non-zero
or raises) gives no figure and stops nothing: native.json and bus.json keep its error under
"not_measured", and the report shows it as a row "not measured" with that error (the end of the
probe's stderr included); every other row is still there, and report.json is written atomically.
A step that wrote no part at all still gets a report, whose rows of that part say so.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from hilrig.apps.bench.baseline import DEFAULT_BASELINE
from hilrig.apps.bench.bus import BUS_MEASUREMENTS, LOCKSTEP_ROUNDS, bus_main
from hilrig.apps.bench.bus_measure import serve_local_node_main
from hilrig.apps.bench.common import LONG_TRACE_CYCLES, ROOT
from hilrig.apps.bench.native import native_main
from hilrig.apps.bench.report import baseline_main, report_main

DEFAULT_OUT = ROOT / "build" / "bench"


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    commands = parser.add_subparsers(dest="command", required=True)
    for name in ("native", "bus", "report", "baseline"):
        command = commands.add_parser(name)
        command.add_argument("--out", type=Path, default=DEFAULT_OUT, help="the bench build folder")
        if name in ("native", "baseline"):
            command.add_argument(
                "--baseline",
                default=DEFAULT_BASELINE,
                metavar="COMMIT",
                help="the commit whose engine the checkout's is compared with (default: %(default)s)",
            )
        if name == "baseline":
            command.add_argument(
                "--remove", action="store_true", help="remove the exported baseline trees, measure nothing"
            )
        if name == "bus":
            command.add_argument("--cycles", type=int, default=2000, help="lockstep cycles per measurement")
            command.add_argument("--warmup", type=int, default=50)
            command.add_argument(
                "--rounds",
                type=int,
                default=LOCKSTEP_ROUNDS,
                help="rounds of the lockstep kinds, alternating; best of each",
            )
            command.add_argument("--sdo", type=int, default=200, help="SDO uploads per server")
            command.add_argument("--free-cycles", type=int, default=10_000)
            command.add_argument("--robot-cycles", type=int, default=500, help="gait cycles per robot size")
            command.add_argument(
                "--long-trace-cycles",
                type=int,
                default=LONG_TRACE_CYCLES,
                help="cycles of the traced run whose trace the report opens in the web viewer (0: none)",
            )
            command.add_argument(
                "--only",
                action="append",
                choices=BUS_MEASUREMENTS,
                metavar="NAME",
                help="measure only this (repeatable): " + ", ".join(BUS_MEASUREMENTS) + " (default: all)",
            )
            command.add_argument(
                "--budget-s",
                type=float,
                default=30.0,
                help="wall-clock cap per lockstep measurement (SDO: twice this); fewer cycles "
                "are measured when it runs out (a loaded machine), and the report says how many",
            )
    serve = commands.add_parser("serve-local-node")
    serve.add_argument("--eds", required=True)
    serve.add_argument("--node-id", type=int, required=True)
    serve.add_argument("--channel", default="vcan0")
    args = parser.parse_args(argv)
    run = {
        "native": native_main,
        "bus": bus_main,
        "report": report_main,
        "baseline": baseline_main,
        "serve-local-node": serve_local_node_main,
    }
    try:
        return run[args.command](args)
    except KeyboardInterrupt:
        print("bench: interrupted; no report written", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
