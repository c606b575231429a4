"""The bus part's measurements (`tools/bench.py bus`), each on the bench's private bus: the
full `Rig` untraced and traced, its floors (a raw socket, the engine's exchange alone,
python-can), robots of several modules, the long traced run, the recorder's upload by block and
segmented SDO, SDO latency against a `canopen.LocalNode` (`serve_local_node_main`, in its own
process), and the free-running firmware's timing. `bus` schedules them.
"""

from __future__ import annotations

import argparse
import contextlib
import itertools
import re
import shutil
import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

from hilrig.apps.bench.common import ROOT, run_within, say

BENCH_COMMAND = (sys.executable, "-m", "hilrig.apps.bench.main")
"""The bench's command line, whose `serve-local-node` runs the LocalNode the SDO latency is
measured against."""
FIRMWARE_NODE_ID = 0x10
LOCAL_NODE_ID = 0x11
SDO_OBJECT = "velocity_kp"  # a REAL32 board parameter: an expedited upload
LONG_TRACE_DIR = "long-trace"
LONG_TRACE_STEP_S = 2.0
"""The long run's velocity setpoint flips sign this often: plots with edges, not flat lines."""


def _sdo_turnarounds(spy: Any) -> dict[int, list[float]]:
    """Per node id: seconds from each SDO request to the node's next answer, both stamped by
    the kernel on receipt (the spy socket saw both)."""
    from boardproto.cia301 import FunctionCode, function_of

    pending: dict[int, float] = {}
    turnaround: dict[int, list[float]] = {FIRMWARE_NODE_ID: [], LOCAL_NODE_ID: []}
    while (message := spy.recv(timeout=0.5)) is not None:
        function, node = function_of(message.arbitration_id)
        if function == FunctionCode.SDO_REQUEST:
            pending[node] = message.timestamp
        elif node in pending and node in turnaround:
            turnaround[node].append(message.timestamp - pending.pop(node))
    return turnaround


def percentile(values: Sequence[float], q: float) -> float:
    ordered = sorted(values)
    if not ordered:
        return float("nan")
    position = (len(ordered) - 1) * q / 100
    low = int(position)
    high = min(low + 1, len(ordered) - 1)
    return ordered[low] + (ordered[high] - ordered[low]) * (position - low)


def drive(rig: Any, setpoint: float = 5.0) -> None:
    """The motor under velocity control toward `setpoint`: the firmware's controller, the
    plant and the traced signals move, as in a scenario, so a traced round traces changing
    values, not a motor standing still."""
    from hilrig.table import ControlMode

    rig.set("control_mode", ControlMode.VELOCITY)
    rig.set("velocity_setpoint", setpoint)


def traced_run(run: Any, cycles: int, table: Any) -> dict[str, Any]:
    """`cycles` lockstep cycles of the full `Rig` in a session of `run` (a `RunDescription`
    with trace=True: trace.rrd in its out_dir, as rig_rate(traced=True) writes it), the motor
    driven (`drive`) with the setpoint flipping sign every LONG_TRACE_STEP_S. Returns the
    trace's path, size and last logged cycle, and the run's wall-clock seconds (the trace's
    close() included)."""
    from hilrig.observe.paths import CYCLE_TIMELINE
    from hilrig.observe.reader import timeline_end
    from hilrig.session.builder import open_session

    session = open_session(run, table=table)
    period_us = run.rig.cycle_us(table)
    try:
        rig, tracer, path = session.rig, session.tracer, session.trace_path
        if rig is None or tracer is None or path is None:
            raise ValueError("traced_run needs a session with a rig and trace=True")
        step = max(1, round(LONG_TRACE_STEP_S * 1e6 / period_us))
        drive(rig)
        start = time.perf_counter()
        done, sign = 0, 1.0
        while done < cycles:
            rig.set("velocity_setpoint", 5.0 * sign)
            chunk = min(step, cycles - done)
            rig.run(cycles=chunk)
            done, sign = done + chunk, -sign
        tracer.close()  # the trace is complete: its cost is part of the run
        elapsed = time.perf_counter() - start
    finally:
        session.close()
    return {
        "trace": str(path),
        "bytes": path.stat().st_size,
        "cycles": done,
        "last_cycle": timeline_end(path, CYCLE_TIMELINE),
        "seconds": elapsed,
        "period_us": period_us,
    }


class BusBench:
    """The bus benchmarks on one private bus (a network namespace with its own vcan0)."""

    def __init__(self, private_bus: Any, out: Path) -> None:
        from boardproto import load_table
        from hilrig.session.run import FirmwareRun, RigRun, RunDescription, TraceRun
        from hilrig.table import RigTable

        self.bus = private_bus
        self.out = out
        self.firmware_exe = out / "bin" / "joint-firmware"
        self.eds = out / "protocol" / "board.eds"
        self.table = RigTable.load()
        self.proto = load_table(ROOT / "protocol" / "board.toml")
        self.run = RunDescription(
            TraceRun(out, trace=False, record=False),
            firmware=FirmwareRun(executable=self.firmware_exe, node_id=FIRMWARE_NODE_ID),
            rig=RigRun(eds=self.eds),
        )
        """Every lockstep run of the bench: the firmware of <out>, no bus log, untraced, the
        rig's other settings the run description's own; each measurement replaces what is its."""
        self.period_us = self.run.rig.cycle_us(self.table)
        """The control period of every run: the table's."""
        self.logs = out / "bench-logs"
        self.logs.mkdir(parents=True, exist_ok=True)
        self._runs = 0

    @contextlib.contextmanager
    def firmware(self, what: str, mode: str = "lockstep") -> Iterator[Any]:
        from hilrig.session.firmware import Firmware

        self._runs += 1
        fw = Firmware(
            self.bus,
            node_id=FIRMWARE_NODE_ID,
            log_path=self.logs / f"{self._runs:02d}-{what}.log",
            period_us=self.period_us,
            executable=self.firmware_exe,
            mode=mode,
        )
        with fw:
            yield fw

    # --- lockstep: the rig (untraced, traced) and the floors -----------------------------------
    def _session(self, what: str, *, traced: bool, bitrate: int | None = None) -> Any:
        """A HIL session of the firmware in lockstep on the bench's bus (`hilrig.session.builder`), no
        bus log; a trace.rrd when `traced`; on a timed bus of `bitrate` unless None."""
        from hilrig.session.builder import open_session

        self._runs += 1
        run = self._run(self.logs / f"{self._runs:02d}-{what}", traced=traced, bitrate=bitrate)
        return open_session(run, table=self.table)

    def _run(self, out_dir: Path, *, traced: bool, bitrate: int | None = None) -> Any:
        """The bench's run (`self.run`) into `out_dir`, traced or not, on the ideal bus or a timed
        one of `bitrate`."""
        from hilrig.session.run import BusRun, TraceRun

        return self.run.replace(
            trace=TraceRun(out_dir, trace=traced, record=False), bus=BusRun(bitrate=bitrate)
        )

    def rig_rate(
        self, cycles: int, warmup: int, budget_s: float, *, traced: bool, bitrate: int | None = None
    ) -> tuple[float, int]:
        """(cycles per second, cycles measured) of the full `Rig` (physics, history, checks) in a
        HIL session (`hilrig.session.builder`, no bus log), with or without a Rerun trace (written to a
        file; its close(), which sends what is pending, is inside the measurement); on a timed bus
        of `bitrate` (`hilrig.engine.bustiming`) unless None."""
        what = "rig-traced" if traced else "rig"
        session = self._session(
            what if bitrate is None else f"{what}-{bitrate}", traced=traced, bitrate=bitrate
        )
        try:
            rig = session.rig
            drive(rig)
            rig.run(cycles=warmup)
            tracer = session.tracer
            # the trace complete (its close() sends what is pending): its cost is part of the run
            finish = tracer.close if tracer is not None else None
            done, elapsed = run_within(rig, budget_s, cycles, finish=finish)
        finally:
            session.close()
        return done / elapsed, done

    def long_trace(self, cycles: int) -> dict[str, Any]:
        """`traced_run` against the firmware through the session rig_rate(traced=True) uses,
        its trace kept in <out>/long-trace/trace.rrd (the path recorded relative to <out>)."""
        folder = self.out / LONG_TRACE_DIR
        shutil.rmtree(folder, ignore_errors=True)  # never an earlier run's trace in its place
        run = traced_run(self._run(folder, traced=True), cycles, self.table)
        return run | {"trace": str(Path(run["trace"]).relative_to(self.out))}

    def robot_rate(self, modules: int, cycles: int, budget_s: float) -> tuple[float, int]:
        """(cycles per second, cycles measured) of a robot of `modules` modules on this bus (the
        same engine: one SYNC, every module's PDOs, the MuJoCo chain) following the gait,
        untraced, no bus log; start-up outside the measurement."""
        from hilrig.apps.gait import TravellingWave
        from hilrig.session.builder import open_session
        from hilrig.session.run import FirmwareRun, RobotRun

        self._runs += 1
        run = self._run(self.logs / f"{self._runs:02d}-robot{modules}", traced=False).replace(
            firmware=FirmwareRun(executable=self.firmware_exe),  # node ids 1..N
            robot=RobotRun(modules),
        )
        session = open_session(run, table=self.table)
        try:
            robot = session.robot
            TravellingWave().drive(robot)
            robot.run(cycles=20)  # warm-up
            done, elapsed = run_within(robot, budget_s, cycles)
        finally:
            session.close()
        return done / elapsed, done

    def robot_floor_rate(self, modules: int, cycles: int, budget_s: float) -> tuple[float, int]:
        """(cycles per second, cycles measured) of the raw N-node floor: the frames of a robot's
        cycle (every module's RPDOs, one SYNC, every due TPDO of every module) exchanged with
        `modules` real firmware processes (node ids 1..N, lockstep) over one raw socket through
        the engine's own exchange (`transport.exchange`, one call into C per cycle): no physics,
        no history, no checks, no trace."""
        from boardproto.cia301 import NMT_COB_ID, SYNC_COUNTER_MAX, NmtCommand, heartbeat_cob_id
        from hilrig.engine.driver import SYNC_FRAMES
        from hilrig.engine.robot import module_ids
        from hilrig.wire.transport import RawCanLink, can_frame, due_table, exchange, open_raw_socket

        node_ids = module_ids(modules)
        layouts = [self._floor_layout(node_id) for node_id in node_ids]
        rpdo_frames = b"".join(p.frame([0] * len(p.names)) for rpdos, _ in layouts for p in rpdos)
        tpdos = [p for _, node_tpdos in layouts for p in node_tpdos]
        due_by_sync = due_table(tpdos)  # every module's the same types: one table for all
        period = len(due_by_sync)
        due = due_by_sync[1:] + due_by_sync[:1]  # due[n % period]: the TPDOs due at SYNC n + 1
        decoders = {p.cob_id: (p.length, p.codec.unpack) for p in tpdos}
        boot_ups = {heartbeat_cob_id(node_id) for node_id in node_ids}
        with self.bus.entered():
            sock = open_raw_socket(self.bus.channel, [*decoders, *boot_ups])
        link = RawCanLink(sock)
        self._runs += 1
        try:
            with contextlib.ExitStack() as stack:
                processes = [
                    stack.enter_context(self._module_firmware(node_id, f"{self._runs:02d}-floor{modules}"))
                    for node_id in node_ids
                ]
                waiting, deadline = set(boot_ups), time.monotonic() + 30 + 5 * modules
                while waiting:
                    frame = link.recv(0.25)
                    if frame is not None:
                        waiting.discard(frame[0])
                    elif time.monotonic() > deadline:
                        raise RuntimeError(f"robot floor: no boot-up from {sorted(waiting)} in time")
                    for fw in processes:
                        fw.check()
                link.send(can_frame(NMT_COB_ID, bytes([NmtCommand.START, 0])))  # 0: every node
                warmup, start, done = 20, 0.0, 0
                for n in range(warmup + cycles):
                    if n == warmup:
                        start = time.perf_counter()
                    elif n > warmup and time.perf_counter() - start > budget_s:
                        break
                    out, got = rpdo_frames + SYNC_FRAMES[n % SYNC_COUNTER_MAX], {}
                    while (taken := exchange(link, out, due[n % period], decoders, got, 5.0)) is not None:
                        out = b""
                        if taken is False:
                            for fw in processes:
                                fw.check()
                            raise RuntimeError(f"robot floor: cycle {n}: a TPDO did not come within 5 s")
                    if n >= warmup:
                        done += 1
                elapsed = time.perf_counter() - start
        finally:
            link.close()
        return done / elapsed, done

    def _module_firmware(self, node_id: int, what: str) -> Any:
        from hilrig.session.firmware import Firmware

        return Firmware(
            self.bus,
            node_id=node_id,
            log_path=self.logs / f"{what}-{node_id:02d}.log",
            period_us=self.period_us,
            executable=self.firmware_exe,
            mode="lockstep",
        )

    # --- SDO: block vs segmented upload of the recorder's 64 KiB -------------------------------
    def recorder_upload(self, rounds: int, budget_s: float) -> dict[str, Any]:
        """Upload throughput of one full recording (8 channels x the samples that fit: the
        recorder's whole buffer, a DOMAIN) by SDO block transfer and by segmented transfer,
        alternating, from the firmware in lockstep; bytes per second of each, best of `rounds`."""
        from boardproto.table import RecorderObject
        from hilrig.apps.capture import CaptureSettings, RecorderClient

        session = self._session("recorder", traced=False)
        try:
            rig = session.rig
            recorder = RecorderClient(rig.node, self.table)
            limits = self.table.board.recorder
            assert limits is not None
            channels = tuple(f.name for f in self.table.board.fields)[: limits.max_channels]
            samples = limits.buffer_values // len(channels)
            recorder.configure(CaptureSettings(channels=channels, samples=samples))
            recorder.arm()
            rig.run(cycles=samples + 10)
            assert recorder.progress().state == "done"
            index = limits.index_of(RecorderObject.DATA)
            rates: dict[str, list[float]] = {"block": [], "segmented": []}
            size = 0
            started = time.perf_counter()
            for _ in range(rounds):
                for kind in rates:
                    if rates["segmented"] and time.perf_counter() - started > budget_s:
                        break  # each kind measured once at least; no upload starts past the budget
                    t0 = time.perf_counter()
                    if kind == "block":
                        data = rig.node.block_upload(index, 0, "bench block upload")
                    else:
                        data = rig.node.upload(index, 0, "bench segmented upload")
                    rates[kind].append(len(data) / (time.perf_counter() - t0))
                    size = len(data)
        finally:
            session.close()
        return {"bytes": size, **{f"{kind}_bytes_per_s": values for kind, values in rates.items()}}

    def _floor_layout(self, node_id: int = FIRMWARE_NODE_ID) -> tuple[list[Any], list[Any]]:
        """The RPDOs the rig sends every cycle (sensors, setpoint stream) and the enabled cyclic
        TPDOs of node `node_id`, compiled from the EDS exactly as the rig compiles them
        (`hilrig.wire.transport`)."""
        import canopen

        from hilrig.wire.transport import PdoDirection, compile_pdos

        network = canopen.Network()  # never connected: the PDO maps only need a home
        node = canopen.RemoteNode(node_id, str(self.eds))
        network.add_node(node)
        node.rpdo.read(from_od=True)
        node.tpdo.read(from_od=True)
        rpdos = [
            p
            for p in compile_pdos(PdoDirection.RPDO, node.rpdo.map).values()
            if p.enabled
            and p.names
            and (
                all(self.table.is_hil_input(n) for n in p.names)
                or set(self.table.setpoint_stream) & set(p.names)
            )
        ]
        tpdos = [
            p for p in compile_pdos(PdoDirection.TPDO, node.tpdo.map).values() if p.is_cyclic and p.names
        ]
        return rpdos, tpdos

    def _await_boot_up(self, next_cob_id: Callable[[], int | None], fw: Any) -> None:
        from boardproto.cia301 import heartbeat_cob_id

        deadline = time.monotonic() + 30
        while next_cob_id() != heartbeat_cob_id(FIRMWARE_NODE_ID):
            fw.check()
            if time.monotonic() > deadline:
                raise RuntimeError("floor: no boot-up from the firmware within 30 s")

    def floor_rate(self, cycles: int, warmup: int, budget_s: float) -> tuple[float, int]:
        """The floor: the same RPDO frames + SYNC out and the same TPDO frames back, over one raw
        socket with kernel filters (`hilrig.wire.transport`), a Python call per frame, no physics,
        no checks, no trace."""
        return self._raw_floor_rate("floor", cycles, warmup, budget_s, engine=False)

    def engine_floor_rate(self, cycles: int, warmup: int, budget_s: float) -> tuple[float, int]:
        """The engine's exchange alone: the same frames through `transport.exchange` as the Rig
        sends and takes them (RPDOs and SYNC out, due TPDOs in and decoded, one call into C per
        cycle on the raw socket), no physics, no history, no trace."""
        return self._raw_floor_rate("engine-floor", cycles, warmup, budget_s, engine=True)

    def _raw_floor_rate(
        self, what: str, cycles: int, warmup: int, budget_s: float, *, engine: bool
    ) -> tuple[float, int]:
        from boardproto.cia301 import (
            NMT_COB_ID,
            SYNC_COB_ID,
            SYNC_COUNTER_MAX,
            NmtCommand,
            heartbeat_cob_id,
            sync_counter,
        )
        from hilrig.wire.transport import RawCanLink, can_frame, due_table, exchange, open_raw_socket

        rpdos, tpdos = self._floor_layout()
        out_frames = [p.frame([0] * len(p.names)) for p in rpdos]
        syncs = [can_frame(SYNC_COB_ID, bytes([sync_counter(n)])) for n in range(SYNC_COUNTER_MAX)]
        receive = [p.cob_id for p in tpdos] + [heartbeat_cob_id(FIRMWARE_NODE_ID)]
        with self.bus.entered():
            sock = open_raw_socket(self.bus.channel, receive)
        link = RawCanLink(sock)
        try:
            with self.firmware(what) as fw:

                def next_cob_id() -> int | None:
                    frame = link.recv(0.25)
                    return frame[0] if frame is not None else None

                self._await_boot_up(next_cob_id, fw)
                link.send(can_frame(NMT_COB_ID, bytes([NmtCommand.START, FIRMWARE_NODE_ID])))
                due_by_sync = due_table(tpdos)
                period = len(due_by_sync)
                due = due_by_sync[1:] + due_by_sync[:1]  # due[n % period]: the TPDOs due at SYNC n + 1
                decoders = {p.cob_id: (p.length, p.codec.unpack) for p in tpdos}
                rpdo_frames = b"".join(out_frames)
                send, recv = link.send, link.recv
                start = 0.0
                done = 0
                for n in range(warmup + cycles):
                    if n == warmup:
                        start = time.perf_counter()
                    elif n > warmup and time.perf_counter() - start > budget_s:
                        break
                    if engine:
                        out, got = rpdo_frames + syncs[n % SYNC_COUNTER_MAX], {}
                        while (taken := exchange(link, out, due[n % period], decoders, got, 5.0)) is not None:
                            out = b""
                            if taken is False:
                                fw.check()
                                raise RuntimeError(f"{what}: cycle {n}: a TPDO did not come within 5 s")
                    else:
                        for frame in out_frames:
                            send(frame)
                        send(syncs[n % SYNC_COUNTER_MAX])
                        for _ in range(len(due[n % period])):
                            if recv(5.0) is None:
                                fw.check()
                                raise RuntimeError(f"{what}: cycle {n}: a TPDO did not come within 5 s")
                    if n >= warmup:
                        done += 1
                elapsed = time.perf_counter() - start
        finally:
            link.close()
        return done / elapsed, done

    def python_can_rate(self, cycles: int, warmup: int, budget_s: float) -> tuple[float, int]:
        """For comparison: the same exchange through python-can's Bus (Message objects)."""
        import can

        from boardproto.cia301 import (
            NMT_COB_ID,
            STANDARD_ID_MASK,
            SYNC_COB_ID,
            NmtCommand,
            heartbeat_cob_id,
            sync_counter,
        )

        rpdos, tpdos = self._floor_layout()
        tpdo_ids = {p.cob_id for p in tpdos}
        bootup = heartbeat_cob_id(FIRMWARE_NODE_ID)
        filters = [{"can_id": cob, "can_mask": STANDARD_ID_MASK} for cob in (*tpdo_ids, bootup)]
        payloads = [(p.cob_id, p.pack([0] * len(p.names))) for p in rpdos]
        with self.bus.open(can_filters=filters) as can_bus, self.firmware("python-can") as fw:

            def next_cob_id() -> int | None:
                msg = can_bus.recv(0.25)
                return msg.arbitration_id if msg is not None else None

            self._await_boot_up(next_cob_id, fw)
            can_bus.send(
                can.Message(
                    arbitration_id=NMT_COB_ID, data=[NmtCommand.START, FIRMWARE_NODE_ID], is_extended_id=False
                )
            )
            start = 0.0
            done = 0
            for n in range(warmup + cycles):
                if n == warmup:
                    start = time.perf_counter()
                elif n > warmup and time.perf_counter() - start > budget_s:
                    break
                for cob, data in payloads:
                    can_bus.send(can.Message(arbitration_id=cob, data=data, is_extended_id=False))
                can_bus.send(
                    can.Message(arbitration_id=SYNC_COB_ID, data=[sync_counter(n)], is_extended_id=False)
                )
                for _ in range(sum(1 for p in tpdos if p.due_at_sync(n + 1))):
                    if can_bus.recv(5.0) is None:
                        fw.check()
                        raise RuntimeError(f"python-can floor: cycle {n}: a TPDO did not come within 5 s")
                if n >= warmup:
                    done += 1
            elapsed = time.perf_counter() - start
        return done / elapsed, done

    # --- SDO latency ---------------------------------------------------------------------------
    def sdo_latency(self, uploads: int, budget_s: float) -> dict[str, Any]:
        import canopen

        from boardproto.cia301 import STANDARD_ID_MASK, FunctionCode, cob_id

        entry = self.table.entry(SDO_OBJECT)
        server = self.bus.popen(
            [
                *BENCH_COMMAND,
                "serve-local-node",
                "--eds",
                str(self.eds),
                "--node-id",
                str(LOCAL_NODE_ID),
                "--channel",
                self.bus.channel,
            ],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        try:
            ready = server.stdout.readline() if server.stdout else ""
            if ready.strip() != "ready":
                raise RuntimeError(f"LocalNode server did not start (said {ready!r})")
            with self.bus.open() as can_bus, self.bus.open() as spy, self.firmware("sdo") as fw:
                # A listener of its own: kernel receive timestamps of every request and answer
                # give each server's turnaround without the Python client's share.
                spy.set_filters(
                    [
                        {"can_id": cob_id(function, n), "can_mask": STANDARD_ID_MASK}
                        for function in (FunctionCode.SDO_RESPONSE, FunctionCode.SDO_REQUEST)
                        for n in (FIRMWARE_NODE_ID, LOCAL_NODE_ID)
                    ]
                )
                network = canopen.Network(can_bus)
                network.connect()
                try:
                    ours = canopen.RemoteNode(FIRMWARE_NODE_ID, str(self.eds))
                    local = canopen.RemoteNode(LOCAL_NODE_ID, str(self.eds))
                    for node in (ours, local):
                        node.sdo.RESPONSE_TIMEOUT = 2.0
                        network.add_node(node)
                    self._wait_sdo(ours, entry.index, entry.subindex, fw.check)
                    self._wait_sdo(local, entry.index, entry.subindex, None)
                    times: dict[str, list[float]] = {"firmware": [], "local_node": []}
                    warmup = 10
                    start_all = time.perf_counter()
                    for i in range(warmup + uploads):
                        if i > warmup and time.perf_counter() - start_all > budget_s:
                            break
                        for name, node in (("firmware", ours), ("local_node", local)):
                            if i > warmup and time.perf_counter() - start_all > budget_s:
                                break  # no upload starts past the budget
                            start = time.perf_counter()
                            node.sdo.upload(entry.index, entry.subindex)
                            elapsed = time.perf_counter() - start
                            if i >= warmup:
                                times[name].append(elapsed)
                finally:
                    network.disconnect()
                turnaround = _sdo_turnarounds(spy)
        finally:
            if server.stdin:
                server.stdin.close()
            try:
                server.wait(5)
            except subprocess.TimeoutExpired:
                server.kill()
                server.wait()
        return {
            name: {
                "median_us": statistics.median(values) * 1e6,
                "p90_us": percentile(values, 90) * 1e6,
                "min_us": min(values) * 1e6,
                "n": len(values),
            }
            for name, values in times.items()
        } | {
            "object": f"{SDO_OBJECT} 0x{entry.index:04X} sub {entry.subindex}",
            "turnaround_median_us": {
                name: statistics.median(turnaround[node_id]) * 1e6 if turnaround[node_id] else None
                for name, node_id in (("firmware", FIRMWARE_NODE_ID), ("local_node", LOCAL_NODE_ID))
            },
        }

    @staticmethod
    def _wait_sdo(node: Any, index: int, subindex: int, check: Callable[[], None] | None) -> None:
        deadline = time.monotonic() + 15
        while True:
            try:
                node.sdo.upload(index, subindex)
                return
            except Exception:
                if check is not None:
                    check()
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.1)

    # --- free-running timing -------------------------------------------------------------------
    def free_running(self, cycles: int) -> dict[str, Any]:
        from boardproto.cia301 import STANDARD_ID_MASK, NmtCommand
        from hilrig.table import ControlMode
        from hilrig.wire.node import BoardNode

        carrier = next(
            p for p in self.proto.tpdos if "velocity_controller_output" in [e.name for e in p.entries]
        )
        cob = carrier.cob_id(FIRMWARE_NODE_ID)
        filters = [{"can_id": cob, "can_mask": STANDARD_ID_MASK}]
        period_s = self.period_us / 1e6
        with (
            self.bus.open(can_filters=filters) as meter,
            self.bus.open() as config_bus,
            self.firmware("free", mode="realtime") as fw,
        ):
            node = BoardNode(config_bus, FIRMWARE_NODE_ID, self.eds, self.table, sdo_timeout_s=2.0)
            try:
                node.wait_until_alive(10.0)
                # No fault may stop the controller: nothing feeds the sensors or the setpoint
                # stream in this test, so the staleness limits go up to their maximum.
                for name in ("watchdog_cycles", "encoder_stale_cycles", "thermistor_stale_cycles"):
                    node.write(name, float(self.table.entry(name).max))
                node.write("fault_clear", 1.0)
                # Only an integral gain: the output ramps by ki * 1 rad/s * 1 ms per cycle, a new
                # value every cycle and far from max_duty for minutes.
                node.write("velocity_kp", 0.0)
                node.write("velocity_kd", 0.0)
                node.write("velocity_ki", 0.001)
                node.write("velocity_setpoint", 1.0)
                sdo = node.remote.sdo
                comm = carrier.communication_index
                sdo.download(comm, 2, bytes([255]))  # event-driven
                sdo.download(comm, 3, (0).to_bytes(2, "little"))  # no inhibit time
                sdo.download(comm, 5, (0).to_bytes(2, "little"))  # no event timer
                node.write("control_mode", float(ControlMode.VELOCITY))
                if node.read("safe_state") != 0.0:
                    flags = node.read("fault_flags")
                    raise RuntimeError(
                        f"free-running: the firmware is in its safe state (fault_flags {flags})"
                    )
                node.nmt(NmtCommand.START)
            finally:
                node.close()
            stamps: list[float] = []
            skip = 20  # the first frames after NMT start
            # A loaded machine (or the emulated VM) misses deadlines: cap the wall-clock time
            # and report how many periods were measured.
            deadline = time.monotonic() + max(3 * cycles * period_s, 30.0)
            while len(stamps) < cycles + 1 + skip:
                msg = meter.recv(2.0)
                if msg is None:
                    fw.check()
                    raise RuntimeError(f"free-running: no TPDO for 2 s after {len(stamps)} frames")
                stamps.append(msg.timestamp)
                if len(stamps) % 2500 == 0:
                    say(f"  free-running: {len(stamps)} of {cycles + 1 + skip} cycle frames")
                if time.monotonic() > deadline:
                    say(f"  free-running: time is up after {len(stamps)} frames")
                    break
            fw.stop()
            log = fw.log_path.read_text(errors="replace")
        stamps = stamps[skip:]
        intervals = [b - a for a, b in itertools.pairwise(stamps)]
        errors_us = [(i - period_s) * 1e6 for i in intervals]
        absolute = [abs(e) for e in errors_us]
        overruns = re.search(r"overruns (\d+)", log)
        return {
            "period_us": self.period_us,
            "cycles": len(intervals),
            "mean_period_us": statistics.fmean(intervals) * 1e6,
            "abs_error_us": {q: percentile(absolute, float(q)) for q in ("50", "90", "99", "99.9")}
            | {"max": max(absolute)},
            "signed_error_us": {"min": min(errors_us), "max": max(errors_us)},
            "late_by_half_a_period": sum(1 for e in errors_us if e > self.period_us / 2),
            "firmware_overruns": int(overruns.group(1)) if overruns else None,
            "method": (
                f"{carrier.name} remapped to event-driven (type 255, inhibit 0) carrying "
                "velocity_controller_output, which changes every cycle; kernel receive timestamps "
                "(SO_TIMESTAMP via python-can) of its frames; error = interval - period"
            ),
        }


def serve_local_node_main(args: argparse.Namespace) -> int:
    """A canopen.LocalNode on its own process and Network, until stdin closes."""
    import can
    import canopen

    bus = can.Bus(interface="socketcan", channel=args.channel)
    network = canopen.Network(bus)
    network.connect()
    network.add_node(canopen.LocalNode(args.node_id, args.eds))
    print("ready", flush=True)
    try:
        sys.stdin.read()
    finally:
        network.disconnect()
    return 0
