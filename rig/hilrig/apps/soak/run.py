"""Soak: a million lockstep cycles against the real firmware on a real SocketCAN bus, with seeded
faults now and then; no cycle may be lost and the firmware's memory must stay flat.

    make soak                                   # SOAK_CYCLES=1000000, through tools/with-vcan
    tools/with-vcan -- .venv/bin/hilrig soak --cycles 20000 --fault-interval 2000

It runs on the rig's engine (no physics: a constant rotation the checks can predict exactly):

* The session (`hilrig.session.builder`, without a Rig): the firmware on a private bus and the
  node (`hilrig.wire.node.BoardNode`: canopen for SDO and NMT).
* The cycles are the engine's lockstep driver's (`hilrig.engine.lockstep`, built by `soak.Soak`):
  its frame link (one raw socket with kernel receive filters for the node's TPDOs, EMCY and
  heartbeat), its codecs compiled from the EDS's PDO mapping, its due-at-SYNC table, its hang
  guard; with the sensor pattern as the plant, a history that keeps nothing, and every problem
  handed to the soak's checker (`checker`) instead of ending the run.
* The PDO layout the checks need (`layout`: the sensor, setpoint and status PDOs, the objects
  the SDO fault reads) is read once from the same generated EDS.
* The SDO transfers a fault needs go through the node; it answers in order, so after the answer
  everything it sent before is in the link's queue (the barrier).
* Per cycle: the sensor RPDO (a constant-speed rotation consistent with the gearbox, see
  `layout.SensorPattern`), the setpoint RPDO (the stream the watchdog watches), SYNC with counter;
  then every TPDO due at that SYNC must arrive once, with its mapped length; the status TPDO
  (safe_state, fault_flags) must say exactly what the injected faults imply; an EMCY that no
  fault explains is a problem.
* Faults (`fault_plan.plan_faults`, seeded, about one per `fault_interval` cycles, every kind
  once during warm-up): a too-short sensor RPDO (EMCY 0x8210, then the error reset the next
  good frame brings), a frame on a COB-ID nobody uses (dropped by the firmware's acceptance
  filter, so the node never receives it), an SDO upload answered with the right value, the
  sensor RPDO withheld until the encoder-stale faults latch at exactly the
  encoder_stale_cycles-th silent cycle, then cleared by writing fault_clear = 1, and an NMT
  stop with SYNCs that must go unanswered, then start (an SDO round trip is the barrier that
  proves nothing was answered while stopped).
* At the end the firmware's own stop line (SIGTERM) must agree with the soak's tally: control
  cycles = SYNCs sent while operational, frames received = frames sent on COB-IDs the node
  accepts (the kernel filter drops the unknown ones before they reach it), frames ignored =
  frames sent while stopped, RPDO length errors = malformed frames, TPDOs and
  EMCYs sent = received, no malformed frames, SDO aborts, send failures or refused writes.
* Memory: VmRSS (and the exact page-table Rss of smaps_rollup) and the open fd count of the
  firmware process every `sample_every` cycles; after warm-up the RSS may grow by at most
  `memory.DEFAULT_RSS_BOUND_KIB`, and the fd count not at all (`memory.memory_verdict`).
  Transparent huge pages are turned off for the firmware process
  (`memory.disable_transparent_huge_pages`): khugepaged would otherwise inflate its RSS by
  megabytes on its own timer (`--keep-thp` to see it).

Pinning the soak and the firmware to one CPU (`--pin`) is off by default: the soak's process
has canopen's receive thread besides its own, and on one CPU those threads and the firmware wait
for each other.

Ctrl-C (or SIGTERM, or the `--stop-file` appearing, which is how `tools/soak` reaches a soak
inside the VM) stops after the current cycle; the report is still written. The report is
written atomically to OUT/report.json, also every minute while running (status "running").
Exit code: 0 passed, 1 a cycle was lost, memory grew or a check failed, 130 interrupted.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from types import FrameType
from typing import Any

from hilrig.apps.soak.checker import SoakError
from hilrig.apps.soak.fault_plan import plan_faults
from hilrig.apps.soak.layout import load_layout
from hilrig.apps.soak.memory import disable_transparent_huge_pages, sample_process
from hilrig.apps.soak.report import (
    RunStatus,
    build_report,
    format_progress,
    print_summary,
    write_json_atomic,
)
from hilrig.apps.soak.soak import BOOT_TIMEOUT_S, RECEIVE_TIMEOUT_S, Soak
from hilrig.errors import RigError
from hilrig.session.firmware import DEFAULT_EXECUTABLE, parse_stop_line
from hilrig.session.run import BusRun, FirmwareRun, RigRun, RunDescription, TraceRun
from hilrig.table import RigTable


class StopRequest:
    """SIGINT/SIGTERM or the stop file: finish the current cycle, then stop. A second signal
    raises KeyboardInterrupt (the report is still written)."""

    def __init__(self, stop_file: Path | None) -> None:
        self.stop_file = stop_file
        self.reason: str | None = None
        self._next_look = 0.0

    def install(self) -> None:
        signal.signal(signal.SIGINT, self._on_signal)
        signal.signal(signal.SIGTERM, self._on_signal)

    def _on_signal(self, number: int, _frame: FrameType | None) -> None:
        if self.reason is not None:
            raise KeyboardInterrupt
        self.reason = signal.Signals(number).name
        print(
            f"\nsoak: {self.reason}: stopping after this cycle (again to abort)", file=sys.stderr, flush=True
        )

    def __call__(self) -> bool:
        if self.reason is None and self.stop_file is not None:
            now = time.monotonic()
            if now >= self._next_look:
                self._next_look = now + 1.0
                if self.stop_file.exists():
                    self.reason = f"stop file {self.stop_file}"
                    print(f"soak: {self.reason}: stopping after this cycle", file=sys.stderr, flush=True)
        return self.reason is not None


def _firmware_pid(process: subprocess.Popen[Any]) -> int:
    """`ip netns exec` execs the firmware in place, so the pid is the firmware's; check."""
    with open(f"/proc/{process.pid}/comm") as comm:
        name = comm.read().strip()
    if name != DEFAULT_EXECUTABLE.name[:15]:
        raise SoakError(f"pid {process.pid} is {name!r}, not the firmware: cannot sample its memory")
    return process.pid


def _pin(pid: int, cpu: int) -> None:
    os.sched_setaffinity(pid, {cpu})


def _pin_this_process(cpu: int) -> None:
    """Every thread of this process (canopen's receive thread too: sched_setaffinity(0) pins
    only the calling thread, and a process split across CPUs loses what pinning is for)."""
    for task in os.listdir("/proc/self/task"):
        with contextlib.suppress(ProcessLookupError):
            os.sched_setaffinity(int(task), {cpu})


def _description(args: argparse.Namespace, out: Path, table: RigTable) -> RunDescription:
    """The soak's run: its firmware on a private bus (or --channel), no rig, trace or bus log;
    the run options of the command line (node id, period, firmware, EDS) over the run's defaults."""
    base = RunDescription(
        TraceRun(out, trace=False, record=False),
        bus=BusRun(host_channel=args.channel),
        firmware=FirmwareRun(boot_timeout_s=BOOT_TIMEOUT_S, term_timeout_s=30.0),
        rig=RigRun(sdo_timeout_s=RECEIVE_TIMEOUT_S),
    )
    return RunDescription.from_arguments(args, table, base)


def run(args: argparse.Namespace, usage_error: Callable[[str], Any]) -> int:
    """Run the soak; the exit code (0 passed, 1 failed, 130 interrupted)."""
    if args.cycles <= 0:
        return usage_error(f"--cycles: expected > 0, got {args.cycles}")
    if args.cpu is None:
        args.cpu = max(os.sched_getaffinity(0))

    out: Path = args.out.resolve()
    table = RigTable.load()
    description = _description(args, out, table)
    # What the run resolved, for the report, the layout and the messages:
    args.period_us = description.rig.cycle_us(table)
    args.node_id = description.node_id(table)
    args.eds, args.firmware = description.rig.eds, description.firmware.executable
    out.mkdir(parents=True, exist_ok=True)
    report_path = out / "report.json"
    layout = load_layout(args.eds, args.node_id)
    plan = plan_faults(args.cycles, args.fault_interval, args.seed, layout)
    stop = StopRequest(args.stop_file)
    stop.install()
    args.thp = "left as the system has it" if args.keep_thp else disable_transparent_huge_pages()

    started_wall = time.time()
    started = time.monotonic()
    cpu_start = os.times()
    soak: Soak | None = None
    firmware_info: dict[str, Any] = {"argv": None, "pid": None, "stop_line": None, "counters": None}
    bus_info: dict[str, Any] = {
        "path": os.environ.get("HIL_BUS_PATH", "unknown (not run through tools/with-vcan)")
    }
    status = RunStatus.PASSED
    error: str | None = None

    def report(run_status: RunStatus) -> dict[str, Any]:
        now = os.times()
        return build_report(
            args=args,
            soak=soak,
            plan=plan,
            status=run_status,
            error=error,
            firmware=firmware_info,
            bus=bus_info,
            started_wall=started_wall,
            duration_s=time.monotonic() - started,
            cycling_s=soak.clock() - soak.started_at if soak and soak.started_at is not None else None,
            driver_cpu_s=(now.user + now.system) - (cpu_start.user + cpu_start.system),
        )

    print(
        f"soak: {args.cycles} cycles, {len(plan.faults)} faults planned (seed {args.seed}, about one "
        f"per {args.fault_interval} cycles), memory judged from cycle {plan.warmup_cycle}, "
        f"bus {bus_info['path']}",
        flush=True,
    )
    from hilrig.session.builder import open_session  # the one place a session is assembled

    session = None
    fw = None
    try:
        session = open_session(description, with_rig=False)
        fw = session.firmware
        assert fw is not None and fw.process is not None
        firmware_info["argv"] = fw.argv
        bus_info |= {
            "namespace": session.private_bus.name if session.private_bus is not None else None,
            "channel": session.private_bus.channel if session.private_bus is not None else args.channel,
        }
        pid = fw.process.pid
        if args.pin:
            _pin_this_process(args.cpu)
            _pin(pid, args.cpu)
        soak = Soak(
            session.node,
            layout,
            plan,
            period_us=args.period_us,
            liveness=fw.check,
            activity=fw.activity,
            stop_requested=stop,
            on_progress=lambda p: print(format_progress(p), flush=True),
            on_checkpoint=lambda: write_json_atomic(report_path, report(RunStatus.RUNNING)),
            sample_every=args.sample_every,
        )
        soak.start()
        firmware_info["pid"] = _firmware_pid(fw.process)
        firmware_info["startup_s"] = round(time.monotonic() - started, 1)
        pinned = f", soak and firmware pinned to CPU {args.cpu}" if args.pin else ""
        print(
            f"soak: node 0x{args.node_id:02X} up {firmware_info['startup_s']} s after the start "
            f"(firmware pid {pid}{pinned}); cycling",
            flush=True,
        )
        soak.probe = lambda cycle, elapsed: sample_process(pid, cycle, elapsed)
        soak.run(args.cycles)
        soak.finish()
        if soak.stopped_by_request:
            status = RunStatus.INTERRUPTED
    except (RigError, OSError) as failure:
        error = f"{type(failure).__name__}: {failure}"
    except KeyboardInterrupt:
        status = RunStatus.INTERRUPTED
        error = "aborted by a second signal"
    finally:
        if session is not None:
            session.close()  # stops the firmware: its stop line is in its log now
        if fw is not None:
            firmware_info["exit_code"] = fw.process.returncode if fw.process is not None else None
            parsed = (
                parse_stop_line(fw.log_path.read_text(errors="replace")) if fw.log_path.exists() else None
            )
            if parsed is not None:
                firmware_info["stop_line"], firmware_info["counters"] = parsed
            firmware_info["log"] = str(fw.log_path)

    data = report(status)
    write_json_atomic(report_path, data)
    print_summary(data, report_path)
    if data["status"] == RunStatus.PASSED:
        return 0
    return 130 if data["status"] == RunStatus.INTERRUPTED else 1
