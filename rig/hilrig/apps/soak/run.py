"""Soak: a million lockstep cycles against the real firmware on a real SocketCAN bus, with seeded
faults now and then; no cycle may be lost and the firmware's memory must stay flat.

    make soak                                   # SOAK_CYCLES=1000000, through tools/with-vcan
    tools/with-vcan -- .venv/bin/hilrig soak --cycles 20000 --fault-interval 2000

It runs on the rig's own engine pieces, with a lean loop of its own on top (no physics: a
constant rotation the checks can predict exactly):

* The session (`hilrig.session.builder`, without a Rig): the firmware on a private bus, canopen's
  RemoteNode for SDO and NMT, and the frame link (`hilrig.wire.transport`: one raw socket with kernel
  receive filters for the node's TPDOs, EMCY and heartbeat).
* The PDO layout (COB-IDs, transmission types, mapped objects and their types) is read once
  from the generated EDS with canopen and compiled into the same codecs the Rig uses
  (`hilrig.wire.transport.compile_pdos`); the due-at-SYNC rule is `boardproto.cia301.due_at_sync`.
* The SDO transfers a fault needs go through canopen's SDO client; the node answers in order, so
  after the answer everything it sent before is in the link's queue (the barrier).
* Per cycle: the sensor RPDO (a constant-speed rotation consistent with the gearbox, see
  `SensorPattern`), the setpoint RPDO (the stream the watchdog watches), SYNC with counter;
  then every TPDO due at that SYNC must arrive once, with its mapped length; the status TPDO
  (safe_state, fault_flags) must say exactly what the injected faults imply; an EMCY that no
  fault explains is a problem.
* Faults (`plan_faults`, seeded, about one per `fault_interval` cycles, every kind once during
  warm-up): a too-short sensor RPDO (EMCY 0x8210, then the error reset the next good frame
  brings), a frame on a COB-ID nobody uses (dropped by the firmware's acceptance filter, so
  the node never receives it), an SDO upload answered with the right
  value, the sensor RPDO withheld until the encoder-stale faults latch at exactly the
  encoder_stale_cycles-th silent cycle, then cleared by writing fault_clear = 1, and an NMT
  stop with SYNCs that must go unanswered, then start (an SDO round trip is the barrier that
  proves nothing was answered while stopped).
* At the end the firmware's own stop line (SIGTERM) must agree with the driver's tally: control
  cycles = SYNCs sent while operational, frames received = frames sent on COB-IDs the node
  accepts (the kernel filter drops the unknown ones before they reach it), frames ignored =
  frames sent while stopped, RPDO length errors = malformed frames, TPDOs and
  EMCYs sent = received, no malformed frames, SDO aborts, send failures or refused writes.
* Memory: VmRSS (and the exact page-table Rss of smaps_rollup) and the open fd count of the
  firmware process every `sample_every` cycles; after warm-up the RSS may grow by at most
  `DEFAULT_RSS_BOUND_KIB`, and the fd count not at all (`memory_verdict`). Transparent huge
  pages are turned off for the firmware process (`disable_transparent_huge_pages`): khugepaged
  would otherwise inflate its RSS by megabytes on its own timer (`--keep-thp` to see it).

Pinning the driver and the firmware to one CPU (`--pin`) is off by default: it made the former
single-threaded driver about 2x faster in the emulated VM, but with canopen's receive thread in
the process it is 1.8x slower (measured: 238 cycles/s pinned, 424 not, 10000 cycles).

Ctrl-C (or SIGTERM, or the `--stop-file` appearing, which is how `tools/soak` reaches a driver
inside the VM) stops after the current cycle; the report is still written. The report is
written atomically to OUT/report.json, also every minute while running (status "running").
Exit code: 0 passed, 1 a cycle was lost, memory grew or a check failed, 130 interrupted.
"""

from __future__ import annotations

import argparse
import contextlib
import ctypes
import datetime
import enum
import itertools
import json
import math
import operator
import os
import random
import signal
import struct
import subprocess
import sys
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from types import FrameType
from typing import Any, Protocol

import canopen
from canopen.sdo import SdoAbortedError, SdoCommunicationError

from boardproto.cia301 import (
    NMT_COB_ID,
    SYNC_COB_ID,
    SYNC_COUNTER_MAX,
    TIME_COB_ID,
    FunctionCode,
    NmtCommand,
    due_at_sync,
    emcy_cob_id,
    heartbeat_cob_id,
    sdo_request_cob_id,
    sdo_response_cob_id,
)
from boardproto.table import ERROR_RESET_CODE
from hilrig import resources
from hilrig.engine.driver import SETPOINT_STREAM
from hilrig.errors import PdoMappingError, RigError
from hilrig.plants import JointParams, thermistor_adc
from hilrig.session.faults import FaultKind
from hilrig.session.firmware import DEFAULT_EXECUTABLE, parse_stop_line
from hilrig.table import BOARD_TABLE, ControlMode, EmcyCode, FaultFlags, RigTable
from hilrig.wire.transport import FrameLink, PdoDirection, PdoLayout, can_frame, compile_pdos

DEFAULT_EDS_PATH = resources.DEFAULT_EDS
DEFAULT_FAULT_INTERVAL = 10_000
"""About one fault per this many cycles (seeded jitter of +-1/4 interval)."""
DEFAULT_SAMPLE_EVERY = 1000
"""Cycles between samples of the firmware's RSS and fd count."""
DEFAULT_RSS_BOUND_KIB = 64
"""Allowed RSS growth from the end of warm-up to the end of the run [KiB].

The firmware allocates nothing after start-up (DESIGN: fixed arrays, no heap), and warm-up ends
only after every fault kind ran once, so every code path and the deepest stack it needs have
been touched by then: a flat process grows by 0 pages. The bound leaves 16 pages (64 KiB) for
page-granular noise that is not a leak: a rarely taken branch faulting in one more page of the
executable or of ASan's shadow of the stack. Anything that allocates per cycle or per fault
blows through it: one 16-byte allocation per cycle is 15 MB over a million cycles (more under
ASan, whose redzones and quarantine make even malloc/free churn without a leak show up as
growth, which is a finding too: no heap after start-up), one 1 KiB allocation per fault episode
is ~95 KiB over the ~95 episodes after warm-up."""
DEFAULT_MAX_LOST = 10
"""Give up after this many lost cycles (the verdict is already "failed" at the first one)."""
RECEIVE_TIMEOUT_S = 10.0
"""Hang guard per blocking receive (wall clock): far above any cycle time, even in the emulated
VM on a busy host; reaching it means the SYNC went unanswered (a lost cycle)."""
BOOT_TIMEOUT_S = 120.0
"""Start-up of the ASan build inside the emulated VM takes several seconds."""
PROGRESS_EVERY_S = 10.0
REPORT_EVERY_S = 60.0
HOUSEKEEPING_EVERY = 256
"""Cycles between looks at the clock (progress, stop request, partial report)."""
SERIES_POINTS = 250
"""The report keeps at most this many RSS samples (evenly thinned); the summary uses all."""

VELOCITY_MODE = float(ControlMode.VELOCITY)
"""The velocity loop (board.toml), so the controllers and the watchdog run."""
MOTOR_COUNTS_PER_CYCLE = 25
"""The sensor pattern turns the motor encoder by this many counts per cycle (38 rad/s at 1 kHz)."""
STALE_ENCODER_BITS = tuple(
    BOARD_TABLE.bitset("fault_flags").bit(name) for name in ("motor_encoder_stale", "output_encoder_stale")
)
"""The fault bits the stale-sensor fault latches (the soak withholds both encoders), with the EMCY
each raises and the object it names (board.toml)."""
STALE_ENCODER_FLAGS = FaultFlags.MOTOR_ENCODER_STALE | FaultFlags.OUTPUT_ENCODER_STALE
MAX_EXTRA_STALE_CYCLES = 5
MAX_STOPPED_SYNCS = 5

EMCY_ERROR_RESET = ERROR_RESET_CODE
EMCY_STALE_SENSOR = EmcyCode[(STALE_ENCODER_BITS[0].emcy or "").upper()]
EMCY_PDO_LENGTH = EmcyCode.PDO_LENGTH_ERROR
RPDO_COMMUNICATION_BASE = 0x1400

EMCY_PAYLOAD = struct.Struct("<HBH")
"""EMCY: error code, error register, then the board's 'about' object index."""


class SoakError(RigError, RuntimeError):
    """The soak could not go on (the firmware stopped answering, too many lost cycles)."""


class SoakFault(enum.StrEnum):
    """The faults the soak injects, spelled as `hilrig.session.faults` spells them (one vocabulary for
    `hilrig sim --fault` and the soak), each with the outcome the soak checks."""

    MALFORMED_RPDO = f"{FaultKind.MALFORMED}:length"
    """The sensor RPDO a few bytes short: EMCY 0x8210, then the error reset."""
    UNKNOWN_COB_ID = f"{FaultKind.MALFORMED}:cob-id"
    """A frame on a COB-ID the node does not use: its acceptance filter drops it (never received)."""
    SDO_UPLOAD = f"{FaultKind.SDO_READ}"
    """An SDO upload between two cycles, answered with the right value."""
    STALE_SENSOR = f"{FaultKind.DROP}:sensors"
    """The sensor RPDO withheld: the encoder-stale faults latch at exactly the limit."""
    NMT_STOP_START = f"{FaultKind.NMT_STOP}"
    """NMT stop, SYNCs that must go unanswered, NMT start."""


class RunStatus(enum.StrEnum):
    PASSED = "passed"
    FAILED = "failed"
    INTERRUPTED = "interrupted"
    RUNNING = "running"


# --- The PDO layout, from the EDS --------------------------------------------------------------
@dataclass(frozen=True)
class SdoObject:
    """An object the soak reads over SDO, with the bytes the node must answer."""

    label: str
    index: int
    subindex: int
    expected: bytes


@dataclass(frozen=True)
class SoakLayout:
    node_id: int
    sensor: PdoLayout
    setpoint: PdoLayout
    tpdos: tuple[PdoLayout, ...]
    """Enabled synchronous cyclic TPDOs (types 1..240): the ones due at SYNCs."""
    status: PdoLayout
    """The TPDO carrying safe_state and fault_flags."""
    encoder_stale_cycles: int
    thermistor_stale_cycles: int
    stale_about: tuple[int, ...]
    """Object indexes the stale-sensor EMCYs name (motor_position, output_position)."""
    fault_clear: tuple[int, int, bytes]
    """index, subindex and the bytes of fault_clear = 1."""
    control_mode: tuple[int, int, bytes]
    """index, subindex and the bytes of control_mode = VELOCITY_MODE."""
    sdo_reads: tuple[SdoObject, ...]
    defaults: dict[str, float]
    """EDS defaults of the parameters the sensor pattern needs (gear ratio, counts per rev)."""
    used_cob_ids: frozenset[int]

    @property
    def emcy_cob_id(self) -> int:
        return emcy_cob_id(self.node_id)

    @property
    def sdo_response_cob_id(self) -> int:
        return sdo_response_cob_id(self.node_id)

    @property
    def sdo_request_cob_id(self) -> int:
        return sdo_request_cob_id(self.node_id)

    @property
    def heartbeat_cob_id(self) -> int:
        return heartbeat_cob_id(self.node_id)

    @property
    def receive_ids(self) -> tuple[int, ...]:
        """What the driver's frame link lets through: the TPDOs, EMCY, heartbeat (the SDO
        answers go to canopen's SDO client)."""
        return (*(p.cob_id for p in self.tpdos), self.emcy_cob_id, self.heartbeat_cob_id)

    @property
    def due_period(self) -> int:
        """SYNC numbers repeat their set of due TPDOs with this period (lcm of the types)."""
        return math.lcm(*(p.transmission_type for p in self.tpdos))

    def due_at(self, sync_number: int) -> tuple[PdoLayout, ...]:
        """TPDOs due at the sync_number-th SYNC since the node entered operational (1 = first)."""
        return tuple(p for p in self.tpdos if due_at_sync(p.transmission_type, sync_number))

    def status_bytes(self, fault_flags: int) -> bytes:
        """The status TPDO's payload for a latched fault mask (safe_state follows it)."""
        return self.status.pack_named(
            {"safe_state": float(bool(fault_flags)), "fault_flags": float(fault_flags)}
        )

    def unknown_cob_ids(self) -> list[int]:
        """11-bit COB-IDs this node neither uses nor listens to (NMT, SYNC, TIME excluded)."""
        return [i for i in range(1, 0x800) if i not in self.used_cob_ids]


def load_layout(eds: str | Path, node_id: int, table: RigTable | None = None) -> SoakLayout:
    """Read the EDS once (canopen, no bus) and freeze what the soak sends and expects.

    PdoMappingError says what is missing when the default mapping lacks the sensor inputs, the
    setpoint stream or the status TPDO the soak relies on."""
    table = table if table is not None else RigTable.load()
    network = canopen.Network()  # never connected: it only gives the PDO maps somewhere to live
    node = canopen.RemoteNode(node_id, str(eds))
    network.add_node(node)
    node.rpdo.read(from_od=True)
    node.tpdo.read(from_od=True)
    od = node.object_dictionary
    rpdos = [p for p in compile_pdos(PdoDirection.RPDO, node.rpdo.map).values() if p.enabled and p.names]
    tpdos = [p for p in compile_pdos(PdoDirection.TPDO, node.tpdo.map).values() if p.enabled and p.names]
    inputs = {io.name for io in table.board.hil_inputs}
    sensor = [p for p in rpdos if set(p.names) == inputs]
    setpoint = [p for p in rpdos if set(SETPOINT_STREAM) <= set(p.names)]
    cyclic = tuple(p for p in tpdos if 1 <= p.transmission_type <= SYNC_COUNTER_MAX)
    status = [p for p in cyclic if "fault_flags" in p.names]
    problems = []
    if not sensor:
        problems.append(f"no enabled RPDO maps exactly the HIL inputs {sorted(inputs)}")
    if not setpoint:
        problems.append(f"no enabled RPDO maps the setpoint stream {SETPOINT_STREAM}")
    if not status or set(status[0].names) != {"safe_state", "fault_flags"}:
        problems.append("no synchronous TPDO maps exactly safe_state and fault_flags")
    if problems:
        raise PdoMappingError(f"{eds}: " + "; ".join(problems))

    def default(name: str) -> float:
        return float(od[name].default)

    def encoded(name: str, value: float) -> tuple[int, int, bytes]:
        var = od[name]
        return var.index, var.subindex, var.encode_raw(value)

    encoder_stale = round(default("encoder_stale_cycles"))
    thermistor_stale = round(default("thermistor_stale_cycles"))
    if thermistor_stale <= encoder_stale + MAX_EXTRA_STALE_CYCLES + 2:
        raise PdoMappingError(
            f"{eds}: thermistor_stale_cycles {thermistor_stale} must exceed encoder_stale_cycles "
            f"{encoder_stale} + {MAX_EXTRA_STALE_CYCLES + 2}: the stale-sensor fault withholds all sensors"
        )
    reads = [
        SdoObject("vendor id", 0x1018, 1, od[0x1018][1].encode_raw(od[0x1018][1].default)),
        SdoObject("product code", 0x1018, 2, od[0x1018][2].encode_raw(od[0x1018][2].default)),
        SdoObject("heartbeat time", 0x1017, 0, od[0x1017].encode_raw(od[0x1017].default)),
    ]
    for name in ("encoder_stale_cycles", "watchdog_cycles", "gear_ratio"):
        index, subindex, data = encoded(name, default(name))
        reads.append(SdoObject(name, index, subindex, data))
    used = {NMT_COB_ID, SYNC_COB_ID, TIME_COB_ID}
    used |= {p.cob_id for p in (*compile_pdos(PdoDirection.RPDO, node.rpdo.map).values(), *tpdos)}
    used |= {emcy_cob_id(node_id), sdo_response_cob_id(node_id), sdo_request_cob_id(node_id)}
    used |= {heartbeat_cob_id(node_id)}
    used |= {int(base) + node_id for base in FunctionCode if FunctionCode.TPDO1 <= base <= FunctionCode.RPDO4}
    return SoakLayout(
        node_id=node_id,
        sensor=sensor[0],
        setpoint=setpoint[0],
        tpdos=cyclic,
        status=status[0],
        encoder_stale_cycles=encoder_stale,
        thermistor_stale_cycles=thermistor_stale,
        stale_about=tuple(od[bit.about].index for bit in STALE_ENCODER_BITS if bit.about),
        fault_clear=encoded("fault_clear", 1.0),
        control_mode=encoded("control_mode", VELOCITY_MODE),
        sdo_reads=tuple(reads),
        defaults={
            name: default(name)
            for name in ("gear_ratio", "encoder_counts_per_rev", "output_encoder_counts_per_rev")
        },
        used_cob_ids=frozenset(used),
    )


# --- What the rig sends ---------------------------------------------------------------------
class SensorPattern:
    """Raw sensor values of firmware cycle k: the joint turning at constant speed.

    The motor encoder advances MOTOR_COUNTS_PER_CYCLE counts per cycle and wraps at 16 bits (the
    firmware unwraps it); the output encoder follows through the gearbox with the EDS's gear
    ratio and counts per revolution, so the spring is never deflected; the thermistor reads the
    ambient temperature and the motor current is zero. The output velocity is the setpoint of
    the velocity loop, so the controllers run near equilibrium for the whole soak.
    """

    def __init__(self, layout: SoakLayout, period_us: int) -> None:
        gear = layout.defaults["gear_ratio"]
        motor_cpr = layout.defaults["encoder_counts_per_rev"]
        output_cpr = layout.defaults["output_encoder_counts_per_rev"]
        self.output_per_motor = output_cpr / (motor_cpr * gear)
        params = JointParams()
        self.thermistor_adc = thermistor_adc(params.ntc_r25_ohm, params.thermistor_pullup_ohm)
        dt = period_us / 1e6
        self.motor_velocity_rad_s = MOTOR_COUNTS_PER_CYCLE / motor_cpr * 2 * math.pi / dt
        self.output_velocity_rad_s = self.motor_velocity_rad_s / gear
        self._sensor = layout.sensor
        canonical = ("motor_encoder_counts", "output_encoder_counts", "thermistor_adc", "motor_current_adc")
        unknown = set(layout.sensor.names) - set(canonical)
        if unknown:
            raise PdoMappingError(
                f"{layout.sensor.label} maps {sorted(unknown)}: the soak has no pattern for it"
            )
        self._order = operator.itemgetter(*(canonical.index(n) for n in layout.sensor.names))

    def values(self, cycle: int) -> tuple[int, int, int, int]:
        """(motor counts, output counts, thermistor ADC, current ADC) of cycle `cycle`."""
        motor = cycle * MOTOR_COUNTS_PER_CYCLE
        return (
            motor & 0xFFFF,
            round(motor * self.output_per_motor) & 0xFFFF,
            self.thermistor_adc,
            0,
        )

    def frame(self, cycle: int) -> bytes:
        """The sensor RPDO of cycle `cycle` as a SocketCAN frame."""
        return self._sensor.frame(self._order(self.values(cycle)))


# --- The fault plan -------------------------------------------------------------------------
@dataclass(frozen=True)
class PlannedFault:
    cycle: int
    """Firmware cycle (SYNCs while operational, 1 = first) whose SYNC the fault comes before."""
    kind: SoakFault
    arg: int
    """Kind-specific, drawn from the seed: the malformed frame's length, the unknown COB-ID, the
    SDO object (modulo the list), cycles withheld beyond the stale limit, SYNCs while stopped."""


@dataclass(frozen=True)
class FaultPlan:
    faults: tuple[PlannedFault, ...]
    warmup_cycle: int
    """Memory is judged from the first sample at or after this cycle: half an interval after the
    first round of faults (every kind once), or half the run when the round does not fit."""
    seed: int
    interval: int

    def counts(self) -> dict[str, int]:
        return dict(Counter(f.kind.value for f in self.faults))


def min_fault_interval(layout: SoakLayout) -> int:
    """Episodes must not overlap: the longest (stale sensor) takes about encoder_stale_cycles
    + MAX_EXTRA_STALE_CYCLES + 3 cycles; keep four times that between faults."""
    return 4 * (layout.encoder_stale_cycles + MAX_EXTRA_STALE_CYCLES + 3)


def plan_faults(cycles: int, interval: int, seed: int, layout: SoakLayout) -> FaultPlan:
    """One fault about every `interval` cycles (+-interval/4, seeded), none in the last half
    interval; the first len(FaultKind) are every kind once in a seeded order. Same arguments,
    same plan."""
    if interval < min_fault_interval(layout):
        raise ValueError(f"fault interval: expected >= {min_fault_interval(layout)} cycles, got {interval}")
    rng = random.Random(seed)
    kinds = list(SoakFault)
    first_round = rng.sample(kinds, len(kinds))
    unknown_ids = layout.unknown_cob_ids()
    faults: list[PlannedFault] = []
    for i in itertools.count():
        nominal = (i + 1) * interval
        if nominal + interval // 2 > cycles:
            break
        at = nominal + (rng.randint(-(interval // 4), interval // 4) if i else 0)
        kind = first_round[i] if i < len(first_round) else rng.choice(kinds)
        arg = {
            SoakFault.MALFORMED_RPDO: lambda: rng.randrange(layout.sensor.length),
            SoakFault.UNKNOWN_COB_ID: lambda: rng.choice(unknown_ids),
            SoakFault.SDO_UPLOAD: lambda: rng.randrange(1 << 16),
            SoakFault.STALE_SENSOR: lambda: rng.randint(1, MAX_EXTRA_STALE_CYCLES),
            SoakFault.NMT_STOP_START: lambda: rng.randint(1, MAX_STOPPED_SYNCS),
        }[kind]()
        faults.append(PlannedFault(at, kind, arg))
    round_done = len(faults) >= len(kinds)
    warmup = faults[len(kinds) - 1].cycle + interval // 2 if round_done else cycles // 2
    return FaultPlan(tuple(faults), warmup, seed, interval)


# --- Memory -------------------------------------------------------------------------------
@dataclass(frozen=True)
class ProcessSample:
    cycle: int
    elapsed_s: float
    vm_rss_kib: int
    rss_anon_kib: int
    rss_exact_kib: int | None
    """Rss of /proc/PID/smaps_rollup: a page-table walk, exact (VmRSS may lag a few pages)."""
    fds: int
    cpu_s: float
    anon_huge_kib: int | None = None
    """AnonHugePages of smaps_rollup: what khugepaged collapsed (0 with THP disabled)."""


def sample_process(pid: int, cycle: int, elapsed_s: float) -> ProcessSample:
    """VmRSS, RssAnon, the exact Rss, open fds and CPU time of process `pid`."""
    status: dict[str, int] = {}
    with open(f"/proc/{pid}/status") as lines:
        for line in lines:
            name, _, rest = line.partition(":")
            if name in ("VmRSS", "RssAnon"):
                status[name] = int(rest.split()[0])
    rollup: dict[str, int] = {}
    with contextlib.suppress(OSError), open(f"/proc/{pid}/smaps_rollup") as lines:
        for line in lines:
            name, _, rest = line.partition(":")
            if name in ("Rss", "AnonHugePages"):
                rollup[name] = int(rest.split()[0])
    with open(f"/proc/{pid}/stat") as stat:
        fields = stat.read().rsplit(")", 1)[1].split()
    cpu_s = (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    return ProcessSample(
        cycle=cycle,
        elapsed_s=round(elapsed_s, 3),
        vm_rss_kib=status["VmRSS"],
        rss_anon_kib=status["RssAnon"],
        rss_exact_kib=rollup.get("Rss"),
        fds=len(os.listdir(f"/proc/{pid}/fd")),
        cpu_s=cpu_s,
        anon_huge_kib=rollup.get("AnonHugePages"),
    )


@dataclass(frozen=True)
class MemoryVerdict:
    ok: bool | None
    """None: not enough samples after warm-up to judge (a short or interrupted run)."""
    reason: str
    bound_kib: int
    warmup_cycle: int
    baseline_cycle: int | None = None
    rss_start_kib: int | None = None
    rss_warmup_kib: int | None = None
    rss_end_kib: int | None = None
    rss_max_after_warmup_kib: int | None = None
    growth_kib: int | None = None
    exact_growth_kib: int | None = None
    fds_warmup: int | None = None
    fds_end: int | None = None
    fds_max: int | None = None


def memory_verdict(samples: Sequence[ProcessSample], warmup_cycle: int, bound_kib: int) -> MemoryVerdict:
    """Flat memory: from the first sample at or after `warmup_cycle` to the last one, VmRSS (and
    the exact Rss, when known) grows by at most `bound_kib` and the fd count never changes."""
    after = [s for s in samples if s.cycle >= warmup_cycle]
    if len(after) < 2 or after[-1].cycle == after[0].cycle:
        return MemoryVerdict(
            None,
            f"inconclusive: {len(after)} sample(s) after warm-up (cycle {warmup_cycle}), need 2",
            bound_kib,
            warmup_cycle,
            rss_start_kib=samples[0].vm_rss_kib if samples else None,
            rss_end_kib=samples[-1].vm_rss_kib if samples else None,
        )
    base, end = after[0], after[-1]
    growth = end.vm_rss_kib - base.vm_rss_kib
    exact = (
        end.rss_exact_kib - base.rss_exact_kib
        if end.rss_exact_kib is not None and base.rss_exact_kib is not None
        else None
    )
    fds_changed = [s for s in after if s.fds != base.fds]
    problems = []
    if growth > bound_kib:
        problems.append(f"VmRSS grew {growth} KiB after warm-up, bound {bound_kib} KiB")
    if exact is not None and exact > bound_kib:
        problems.append(f"exact Rss grew {exact} KiB after warm-up, bound {bound_kib} KiB")
    if fds_changed:
        first = fds_changed[0]
        problems.append(f"open fds went from {base.fds} to {first.fds} at cycle {first.cycle}")
    reason = "; ".join(problems) or (
        f"flat: VmRSS {base.vm_rss_kib} -> {end.vm_rss_kib} KiB ({growth:+d}) from cycle {base.cycle} "
        f"to {end.cycle}, bound {bound_kib} KiB; fds {base.fds} throughout"
    )
    return MemoryVerdict(
        not problems,
        reason,
        bound_kib,
        warmup_cycle,
        baseline_cycle=base.cycle,
        rss_start_kib=samples[0].vm_rss_kib,
        rss_warmup_kib=base.vm_rss_kib,
        rss_end_kib=end.vm_rss_kib,
        rss_max_after_warmup_kib=max(s.vm_rss_kib for s in after),
        growth_kib=growth,
        exact_growth_kib=exact,
        fds_warmup=base.fds,
        fds_end=end.fds,
        fds_max=max(s.fds for s in samples),
    )


def thin(items: Sequence[Any], points: int) -> list[Any]:
    """At most `points` items, evenly spread, first and last always kept."""
    if len(items) <= points:
        return list(items)
    step = (len(items) - 1) / (points - 1)
    return [items[round(i * step)] for i in range(points)]


@dataclass
class Tally:
    """What the driver put on the bus and got back; the firmware's stop line must agree."""

    syncs_operational: int = 0
    syncs_stopped: int = 0
    frames_sent: int = 0
    """Frames on COB-IDs the node accepts: the firmware's 'frames received'."""
    ignored_expected: int = 0
    frames_filtered: int = 0
    """Frames on COB-IDs outside the node's acceptance filter: on the bus, never received."""
    length_errors: int = 0
    tpdos_received: int = 0
    emcy_received: int = 0
    heartbeats: int = 0

    def expected_counters(self) -> dict[str, int]:
        return {
            "cycles": self.syncs_operational,
            "overruns": 0,
            "frames received": self.frames_sent,
            "ignored": self.ignored_expected,
            "malformed": 0,
            "SDO aborts": 0,
            "RPDO length errors": self.length_errors,
            "TPDOs sent": self.tpdos_received,
            "EMCY": self.emcy_received,
            "send failures": 0,
            "bus error frames": 0,
            "receive overruns": 0,
            "board refused writes": 0,
        }


def compare_counters(expected: dict[str, int], actual: dict[str, int]) -> list[str]:
    """'firmware: frames received 9001, expected 9002' for every counter that disagrees."""
    mismatches = []
    for name, value in expected.items():
        if name not in actual:
            mismatches.append(f"firmware stop line has no '{name}' counter")
        elif actual[name] != value:
            mismatches.append(f"firmware: {name} {actual[name]}, expected {value}")
    return mismatches


# --- The driver ---------------------------------------------------------------------------
class SdoPort(Protocol):
    """An SDO client: canopen's `SdoClient` (`RemoteNode.sdo`), or a stand-in in tests. Raises
    canopen's SdoAbortedError / SdoCommunicationError."""

    def upload(self, index: int, subindex: int) -> bytes: ...

    def download(self, index: int, subindex: int, data: bytes) -> None: ...


@dataclass(frozen=True)
class LostCycle:
    cycle: int
    sync_counter: int
    missing: tuple[str, ...]
    received: tuple[str, ...]
    late: tuple[str, ...] = ()


@dataclass
class SoakProgress:
    cycle: int
    cycles: int
    elapsed_s: float
    rate: float
    recent_rate: float
    sample: ProcessSample | None
    faults: int
    lost: int
    problems: int


Emcy = tuple[int, int]
"""(error code, the object index the board names)."""


class SoakDriver:
    """The lean lockstep master on the rig's frame link (`hilrig.wire.transport`), with canopen's SDO
    client for the SDO it needs. `start()` waits for the node's boot-up and starts it; `run()`
    drives cycles until the count is reached or a stop is requested; `finish()` drains the bus.

    `probe` samples the firmware process (None: no memory figures), `liveness` raises
    FirmwareError once the process died, `stop_requested` is polled every HOUSEKEEPING_EVERY cycles.
    """

    def __init__(
        self,
        link: FrameLink,
        sdo: SdoPort,
        layout: SoakLayout,
        plan: FaultPlan,
        *,
        period_us: int = 1000,
        probe: Callable[[int, float], ProcessSample] | None = None,
        liveness: Callable[[], None] = lambda: None,
        stop_requested: Callable[[], bool] = lambda: False,
        on_progress: Callable[[SoakProgress], None] | None = None,
        on_checkpoint: Callable[[], None] | None = None,
        sample_every: int = DEFAULT_SAMPLE_EVERY,
        max_lost: int = DEFAULT_MAX_LOST,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.layout = layout
        self.plan = plan
        self.pattern = SensorPattern(layout, period_us)
        self.probe = probe
        self.liveness = liveness
        self.stop_requested = stop_requested
        self.on_progress = on_progress
        self.on_checkpoint = on_checkpoint
        self.sample_every = sample_every
        self.max_lost = max_lost
        self.clock = clock
        self._send = link.send
        self._recv = link.recv
        self.sdo = sdo
        self.tally = Tally()
        self.cycle = 0
        """Firmware cycles so far: SYNCs sent while the node was operational."""
        self.cycles_target = 0
        self.lost: list[LostCycle] = []
        self.problems: list[str] = []
        self.problem_count = 0
        self.faults_done: Counter[str] = Counter()
        self.samples: list[ProcessSample] = []
        self.emcy_log: list[tuple[int, int, int]] = []
        """(cycle, code, about) of every EMCY, for the report (a few hundred at most)."""
        self.heartbeat_states: Counter[int] = Counter()
        self.velocity_samples: list[tuple[int, float, float]] = []
        self.started_at: float | None = None
        self.stopped_by_request = False
        self._sync_count = 0
        self._sync_number = 0  # SYNCs since the node entered operational
        self._cycle_emcy: list[Emcy] = []
        self._last_status = b""
        self._velocity_tpdo = next((p for p in layout.tpdos if "motor_velocity" in p.names), None)
        self._velocity_payload = b""
        self._velocity_cob = self._velocity_tpdo.cob_id if self._velocity_tpdo is not None else -1
        self._tpdo_mask = {p.cob_id: 1 << i for i, p in enumerate(layout.tpdos)}
        self._tpdo_length = {p.cob_id: p.length for p in layout.tpdos}
        self._tpdo_by_cob = {p.cob_id: p for p in layout.tpdos}
        period = layout.due_period
        self._due_period = period
        self._due_mask = [
            sum(self._tpdo_mask[p.cob_id] for p in layout.due_at(n if n else period)) for n in range(period)
        ]
        self._healthy_status = layout.status_bytes(0)
        self._latched_status = layout.status_bytes(STALE_ENCODER_FLAGS)
        setpoints = {
            n: self.pattern.output_velocity_rad_s if n == "velocity_setpoint" else 0.0
            for n in layout.setpoint.names
        }
        self._setpoint_frame = can_frame(layout.setpoint.cob_id, layout.setpoint.pack_named(setpoints))
        self._sync_frames = [can_frame(SYNC_COB_ID, bytes([c])) for c in range(1, SYNC_COUNTER_MAX + 1)]
        self.sdo_reads = (
            *layout.sdo_reads,
            SdoObject("control_mode", *layout.control_mode),
            *(
                SdoObject(name, *address, layout.setpoint.object_bytes(name, setpoints[name]))
                for name, address in zip(layout.setpoint.names, layout.setpoint.addresses, strict=True)
            ),
        )
        """What the SDO-upload fault reads: the EDS's fixed objects and what the driver set."""
        self.stale_limit = layout.encoder_stale_cycles
        self._next_sample = 0
        self._next_housekeeping = HOUSEKEEPING_EVERY
        self._next_progress_s = 0.0
        self._next_checkpoint_s = 0.0
        self._last_progress = (0, 0.0)

    # --- Raw frames -----------------------------------------------------------------------
    def _send_counted(self, cob_id: int, data: bytes, *, filtered: bool = False) -> None:
        """`filtered`: a COB-ID outside the node's acceptance filter (the kernel drops it)."""
        self._send(can_frame(cob_id, data))
        if filtered:
            self.tally.frames_filtered += 1
        else:
            self.tally.frames_sent += 1

    def _problem(self, text: str) -> None:
        self.problem_count += 1
        if len(self.problems) < 100:
            self.problems.append(f"cycle {self.cycle}: {text}")

    def _other_frame(self, cob_id: int, data: bytes) -> bool:
        """EMCY or heartbeat between TPDOs; returns False for anything else."""
        if cob_id == self.layout.emcy_cob_id:
            code, _register, about = EMCY_PAYLOAD.unpack_from(data)
            self.tally.emcy_received += 1
            self._cycle_emcy.append((code, about))
            if len(self.emcy_log) < 1000:
                self.emcy_log.append((self.cycle, code, about))
            return True
        if cob_id == self.layout.heartbeat_cob_id:
            self.tally.heartbeats += 1
            self.heartbeat_states[data[0]] += 1
            return True
        return False

    # --- One cycle ------------------------------------------------------------------------
    def _cycle(self, *, sensor: bool = True, status: bytes | None = None, emcy: Sequence[Emcy] = ()) -> None:
        """One lockstep cycle: RPDOs, SYNC, then every TPDO due at it, checked.

        `status` is the status TPDO payload the injected faults imply (default: no fault);
        `emcy` the EMCYs this cycle must bring (default: none)."""
        k = self.cycle + 1
        send = self._send
        if sensor:
            send(self.pattern.frame(k))
        send(self._setpoint_frame)
        send(self._sync_frames[self._sync_count % SYNC_COUNTER_MAX])
        self._sync_count += 1
        self._sync_number += 1
        self.cycle = k
        tally = self.tally
        tally.frames_sent += 3 if sensor else 2
        tally.syncs_operational += 1
        due = self._due_mask[self._sync_number % self._due_period]
        expected_status = self._healthy_status if status is None else status
        bits, lengths, status_cob = self._tpdo_mask, self._tpdo_length, self.layout.status.cob_id
        velocity_cob = self._velocity_cob
        recv = self._recv
        got = 0
        while got != due:
            frame = recv(RECEIVE_TIMEOUT_S)
            if frame is None:
                self._lost_cycle(due, got)
                break
            cob_id, data = frame
            bit = bits.get(cob_id)
            if bit is None:
                if not self._other_frame(cob_id, data):
                    self._problem(f"unexpected frame 0x{cob_id:03X} {data.hex()}")
                continue
            tally.tpdos_received += 1
            if bit & got or not bit & due or len(data) != lengths[cob_id]:
                self._tpdo_problem(cob_id, len(data), bit & got, bit & due)
            got |= bit & due
            if cob_id == status_cob:
                self._last_status = data
                if data != expected_status:
                    self._status_problem(expected_status)
            elif cob_id == velocity_cob:
                self._velocity_payload = data
        if self._cycle_emcy or emcy:
            self._check_emcy(emcy)

    def _tpdo_problem(self, cob_id: int, length: int, twice: int, due: int) -> None:
        pdo = self._tpdo_by_cob[cob_id]
        if twice:
            self._problem(f"{pdo.label} arrived twice after one SYNC")
        elif not due:
            self._problem(f"{pdo.label} arrived but is not due at SYNC {self._sync_number} since operational")
        else:
            self._problem(f"{pdo.label} has {length} bytes, its mapping {pdo.length}")

    def _status_problem(self, expected: bytes) -> None:
        codec = self.layout.status.codec
        names = self.layout.status.names
        got = dict(zip(names, codec.unpack(self._last_status[: codec.size]), strict=True))
        want = dict(zip(names, codec.unpack(expected), strict=True))
        self._problem(f"{self.layout.status.label}: expected {want}, got {got}")

    def _check_emcy(self, expected: Sequence[Emcy]) -> None:
        got, self._cycle_emcy = self._cycle_emcy, []
        if sorted(got) != sorted(expected):
            words = ", ".join(f"0x{code:04X} about 0x{about:04X}" for code, about in got) or "none"
            wanted = ", ".join(f"0x{code:04X} about 0x{about:04X}" for code, about in expected) or "none"
            self._problem(f"EMCY: expected {wanted}, got {words}")

    def _lost_cycle(self, due: int, got: int) -> None:
        labels = {p.cob_id: p.label for p in self.layout.tpdos}
        missing = tuple(labels[c] for c, b in self._tpdo_mask.items() if due & b and not got & b)
        received = tuple(labels[c] for c, b in self._tpdo_mask.items() if got & b)
        self.liveness()  # a dead firmware reads as a crash, not as a lost cycle
        late = self._barrier(late_ok=True)
        self.lost.append(
            LostCycle(self.cycle, (self._sync_count - 1) % SYNC_COUNTER_MAX + 1, missing, received, late)
        )
        self._problem(
            f"lost: {', '.join(missing)} did not arrive within {RECEIVE_TIMEOUT_S:g} s"
            + (f" (late: {', '.join(late)})" if late else "")
        )
        if len(self.lost) > self.max_lost:
            raise SoakError(
                f"{len(self.lost)} lost cycles (limit {self.max_lost}); last at cycle {self.cycle}"
            )

    # --- SDO ------------------------------------------------------------------------------
    def _sdo(
        self,
        what: str,
        transfer: Callable[[], bytes | None],
        *,
        late_ok: bool = False,
        late: list[str] | None = None,
    ) -> tuple[bool, bytes | None]:
        """One SDO transfer through canopen (one request frame: every object here is expedited),
        then whatever the node sent before its answer: the answer comes after it, so it is in
        the link's queue by now. EMCY and heartbeat are kept, a TPDO is a problem (between SYNCs
        nothing is due) unless `late_ok` (resynchronising after a lost cycle: it is late).
        Returns (whether it succeeded, what the transfer returned); a failure is a problem."""
        self.tally.frames_sent += 1
        try:
            result = transfer()
            ok = True
        except SdoAbortedError as error:
            self._problem(f"{what}: abort 0x{error.code:08X}")
            result, ok = None, False
        except SdoCommunicationError as error:
            self.liveness()
            self._problem(f"{what}: no SDO answer within {RECEIVE_TIMEOUT_S:g} s ({error})")
            result, ok = None, False
        while (frame := self._recv(0.0)) is not None:
            cob_id, data = frame
            if cob_id in self._tpdo_mask:
                self.tally.tpdos_received += 1
                label = self._tpdo_by_cob[cob_id].label
                if late_ok and late is not None:
                    late.append(label)
                else:
                    self._problem(f"{label} arrived between SYNCs (no SYNC was due an answer)")
            elif not self._other_frame(cob_id, data):
                self._problem(f"unexpected frame 0x{cob_id:03X} while waiting for an SDO answer")
        return ok, result

    def sdo_upload(self, obj: SdoObject, *, late_ok: bool = False, late: list[str] | None = None) -> bool:
        """Read `obj` and check the answer; False (and a problem) when it is wrong."""
        what = f"SDO upload {obj.label}"
        ok, answer = self._sdo(
            what, lambda: self.sdo.upload(obj.index, obj.subindex), late_ok=late_ok, late=late
        )
        if ok and answer != obj.expected:
            self._problem(
                f"{what} 0x{obj.index:04X}:{obj.subindex}: expected {obj.expected.hex()}, got "
                f"{(answer or b'').hex()}"
            )
            return False
        return ok

    def sdo_download(self, label: str, index: int, subindex: int, data: bytes) -> bool:
        ok, _ = self._sdo(f"SDO download {label}", lambda: self.sdo.download(index, subindex, data))
        return ok

    def _barrier(self, *, late_ok: bool = False) -> tuple[str, ...]:
        """An SDO round trip: the node answers in order, so whatever it sent before is in."""
        late: list[str] = []
        self.sdo_upload(self.layout.sdo_reads[0], late_ok=late_ok, late=late)
        return tuple(late)

    # --- Start, run, finish -----------------------------------------------------------------
    def start(self, boot_timeout_s: float = BOOT_TIMEOUT_S) -> None:
        """Wait for the boot-up, put the node in velocity mode, check the stale limit, start it."""
        deadline = self.clock() + boot_timeout_s
        while True:  # the boot-up, or (when it went out before the link was open) a heartbeat
            frame = self._recv(1.0)
            if frame is None:
                self.liveness()
                if self.clock() > deadline:
                    raise SoakError(
                        f"no boot-up or heartbeat from node 0x{self.layout.node_id:02X} within "
                        f"{boot_timeout_s} s"
                    )
                continue
            if frame[0] == self.layout.heartbeat_cob_id:
                break
        stale = next(o for o in self.layout.sdo_reads if o.label == "encoder_stale_cycles")
        if not self.sdo_upload(stale):
            raise SoakError("the node's encoder_stale_cycles is not the EDS default: " + self.problems[-1])
        if not self.sdo_download("control_mode", *self.layout.control_mode):
            raise SoakError("cannot put the node in velocity mode: " + self.problems[-1])
        self._nmt(NmtCommand.START)
        self.started_at = self.clock()
        self._next_progress_s = self.started_at + PROGRESS_EVERY_S
        self._next_checkpoint_s = self.started_at + REPORT_EVERY_S
        self._last_progress = (0, self.started_at)

    def _nmt(self, command: NmtCommand) -> None:
        self._send_counted(NMT_COB_ID, bytes([int(command), self.layout.node_id]))
        if command is NmtCommand.START:
            self._sync_number = 0  # the node counts SYNCs for its TPDOs from here

    def run(self, cycles: int) -> None:
        """Drive cycles until `cycles` firmware cycles ran or a stop was requested."""
        self.cycles_target = cycles
        if not self.samples:
            self._sample(force=True)
        faults = iter(self.plan.faults)
        next_fault = next(faults, None)
        inject = {
            SoakFault.MALFORMED_RPDO: self._malformed_rpdo,
            SoakFault.UNKNOWN_COB_ID: self._unknown_cob_id,
            SoakFault.SDO_UPLOAD: self._sdo_upload_fault,
            SoakFault.STALE_SENSOR: self._stale_sensor,
            SoakFault.NMT_STOP_START: self._nmt_stop_start,
        }
        cycle = self._cycle
        while self.cycle < cycles:
            if next_fault is not None and self.cycle + 1 >= next_fault.cycle:
                inject[next_fault.kind](next_fault)
                self.faults_done[next_fault.kind.value] += 1
                next_fault = next(faults, None)
            else:
                cycle()
            if self.cycle >= self._next_sample:
                self._sample()
            if self.cycle >= self._next_housekeeping:
                self._next_housekeeping = self.cycle + HOUSEKEEPING_EVERY
                if self._housekeeping():
                    self.stopped_by_request = True
                    break

    def finish(self) -> None:
        """Drain: an SDO round trip proves nothing more is on its way; sample memory once more."""
        self._barrier()
        if self._cycle_emcy:
            self._check_emcy(())
        if not self.samples or self.samples[-1].cycle != self.cycle:
            self._sample(force=True)

    def _sample(self, *, force: bool = False) -> None:
        self._next_sample = (self.cycle // self.sample_every + 1) * self.sample_every
        if self._velocity_tpdo is not None:
            self._record_velocity()
        if self.probe is None:
            return
        elapsed = self.clock() - (self.started_at or self.clock())
        sample = self.probe(self.cycle, elapsed)
        if force or not self.samples or self.samples[-1].cycle != sample.cycle:
            self.samples.append(sample)

    def _record_velocity(self) -> None:
        """Decode the latest motor and output velocity (once per sample): a content check of a
        TPDO that is otherwise only counted, and a window on how the estimate ages."""
        pdo = self._velocity_tpdo
        if pdo is None or not self._velocity_payload:
            return
        values = dict(zip(pdo.names, pdo.codec.unpack_from(self._velocity_payload), strict=True))
        self.velocity_samples.append(
            (self.cycle, values["motor_velocity"], values.get("output_velocity", math.nan))
        )

    def _housekeeping(self) -> bool:
        """Progress, checkpoint, stop request; True to stop."""
        now = self.clock()
        if self.on_progress is not None and now >= self._next_progress_s:
            self._next_progress_s = now + PROGRESS_EVERY_S
            self.on_progress(self.progress(now))
        if self.on_checkpoint is not None and now >= self._next_checkpoint_s:
            self._next_checkpoint_s = now + REPORT_EVERY_S
            self.on_checkpoint()
        return self.stop_requested()

    def progress(self, now: float | None = None) -> SoakProgress:
        now = self.clock() if now is None else now
        started = self.started_at if self.started_at is not None else now
        elapsed = now - started
        last_cycle, last_time = self._last_progress
        recent = (self.cycle - last_cycle) / (now - last_time) if now > last_time else 0.0
        self._last_progress = (self.cycle, now)
        return SoakProgress(
            cycle=self.cycle,
            cycles=self.cycles_target,
            elapsed_s=elapsed,
            rate=self.cycle / elapsed if elapsed > 0 else 0.0,
            recent_rate=recent,
            sample=self.samples[-1] if self.samples else None,
            faults=sum(self.faults_done.values()),
            lost=len(self.lost),
            problems=self.problem_count,
        )

    # --- Faults ---------------------------------------------------------------------------
    def _malformed_rpdo(self, fault: PlannedFault) -> None:
        """A sensor RPDO shorter than its mapping: refused (EMCY 0x8210 naming 0x1400+n), and the
        good frame right after ends the error (EMCY error reset); the cycle runs normally."""
        sensor = self.layout.sensor
        self._send_counted(sensor.cob_id, bytes((fault.cycle + i) & 0xFF for i in range(fault.arg)))
        self.tally.length_errors += 1
        about = RPDO_COMMUNICATION_BASE + sensor.number - 1
        self._cycle(emcy=((EMCY_PDO_LENGTH, about), (EMCY_ERROR_RESET, 0)))

    def _unknown_cob_id(self, fault: PlannedFault) -> None:
        """A frame on a COB-ID this node does not use: its acceptance filter drops it (neither
        received nor ignored in the stop line), no answer, the cycle runs normally."""
        length = fault.cycle % 9
        self._send_counted(
            fault.arg, bytes((fault.cycle * 7 + i) & 0xFF for i in range(length)), filtered=True
        )
        self._cycle()

    def _sdo_upload_fault(self, fault: PlannedFault) -> None:
        """An SDO upload between two cycles, answered with the right value."""
        self.sdo_upload(self.sdo_reads[fault.arg % len(self.sdo_reads)])
        self._cycle()

    def _stale_sensor(self, fault: PlannedFault) -> None:
        """Withhold the sensor RPDO: both encoder-stale bits latch exactly at the
        encoder_stale_cycles-th silent cycle (EMCY 0x5000 naming each position), stay latched
        after the sensor is back, and clear in the first cycle after fault_clear = 1 (error resets)."""
        limit = self.stale_limit
        latched = self._latched_status
        stale_emcy = tuple((EMCY_STALE_SENSOR, about) for about in self.layout.stale_about)
        for silent in range(1, limit + fault.arg + 1):
            if silent < limit:
                self._cycle(sensor=False)
            else:
                self._cycle(sensor=False, status=latched, emcy=stale_emcy if silent == limit else ())
        for _ in range(2):
            self._cycle(status=latched)  # the cause is gone, the latch holds
        self.sdo_download("fault_clear", *self.layout.fault_clear)
        self._cycle(emcy=tuple((EMCY_ERROR_RESET, 0) for _ in self.layout.stale_about))

    def _nmt_stop_start(self, fault: PlannedFault) -> None:
        """NMT stop, then `arg` cycles' worth of RPDOs and SYNC the node must ignore (no cycle, no
        TPDO), NMT start, and an SDO round trip as the barrier: any TPDO before its answer was
        sent while stopped."""
        self._nmt(NmtCommand.STOP)
        for _ in range(fault.arg):
            self._send(self.pattern.frame(self.cycle + 1))
            self._send(self._setpoint_frame)
            self._send(self._sync_frames[self._sync_count % SYNC_COUNTER_MAX])
            self._sync_count += 1
            self.tally.frames_sent += 3
            self.tally.ignored_expected += 3
            self.tally.syncs_stopped += 1
        self._nmt(NmtCommand.START)
        self._barrier()
        self._cycle()


# --- Report -------------------------------------------------------------------------------
def write_json_atomic(path: Path, data: dict[str, Any]) -> None:
    """Write `data` as JSON to `path` via a temporary file and rename: never half a file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(json.dumps(data, indent=2) + "\n")
    os.replace(tmp, path)


def format_duration(seconds: float) -> str:
    seconds = max(0, round(seconds))
    hours, rest = divmod(seconds, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours} h {minutes:02d} min" if hours else f"{minutes} min {secs:02d} s"


def format_progress(p: SoakProgress) -> str:
    left = (p.cycles - p.cycle) / p.recent_rate if p.recent_rate > 0 else float("inf")
    eta = format_duration(left) if math.isfinite(left) else "?"
    memory = f"; RSS {p.sample.vm_rss_kib} KiB, fds {p.sample.fds}" if p.sample is not None else ""
    return (
        f"soak: {p.cycle}/{p.cycles} cycles ({100 * p.cycle / max(p.cycles, 1):.1f} %), "
        f"{p.recent_rate:.0f} cycles/s (mean {p.rate:.0f}), ETA {eta}{memory}; "
        f"faults {p.faults}, lost {p.lost}, problems {p.problems}"
    )


# --- Command line -------------------------------------------------------------------------
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
    only the calling thread, and a process split across CPUs was measured 2.4x slower here)."""
    for task in os.listdir("/proc/self/task"):
        with contextlib.suppress(ProcessLookupError):
            os.sched_setaffinity(int(task), {cpu})


_PR_SET_THP_DISABLE = 41


def disable_transparent_huge_pages() -> str:
    """PR_SET_THP_DISABLE for this process and (inherited across fork and exec) the firmware it
    starts; returns what the report says about THP.

    With THP "always" (Debian's kernels, the micro-VM's), khugepaged collapses the firmware's
    sparse anonymous mappings (ASan's shadow and heap) into 2 MiB pages on its own timer: VmRSS
    jumps by megabytes a few seconds into the run (measured: +8 MiB at 8 s, AnonHugePages 0 ->
    10 MiB, then flat) although the firmware touched no new page. That is the kernel's memory
    policy, not the firmware's use (a real board has no THP), and it would make a flat process
    look like it grew whenever a collapse lands after warm-up."""
    system = "unknown"
    with contextlib.suppress(OSError):
        system = Path("/sys/kernel/mm/transparent_hugepage/enabled").read_text().strip()
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.prctl(_PR_SET_THP_DISABLE, 1, 0, 0, 0) != 0:
        return f"system setting {system}; PR_SET_THP_DISABLE failed ({os.strerror(ctypes.get_errno())})"
    return f"disabled for the firmware (PR_SET_THP_DISABLE); system setting {system}"


def build_report(
    *,
    args: argparse.Namespace,
    driver: SoakDriver | None,
    plan: FaultPlan,
    status: RunStatus,
    error: str | None,
    firmware: dict[str, Any],
    bus: dict[str, Any],
    started_wall: float,
    duration_s: float,
    driver_cpu_s: float,
    cycling_s: float | None = None,
) -> dict[str, Any]:
    """The soak report (JSON-ready). `status` is the run's outcome before the verdicts."""
    samples = driver.samples if driver is not None else []
    verdict = memory_verdict(samples, plan.warmup_cycle, args.rss_bound_kib)
    tally = driver.tally if driver is not None else Tally()
    stop = firmware.get("counters")
    mismatches = compare_counters(tally.expected_counters(), stop) if stop is not None else []
    if stop is None and status is not RunStatus.RUNNING:
        mismatches = ["no stop line from the firmware (killed, or crashed?)"]
    lost = driver.lost if driver is not None else []
    problems = driver.problems if driver is not None else []
    problem_count = driver.problem_count if driver is not None else 0
    failures = []
    if lost:
        failures.append(f"{len(lost)} lost cycle(s)")
    if problem_count:
        failures.append(f"{problem_count} check(s) failed")
    if verdict.ok is False:
        failures.append("memory: " + verdict.reason)
    if mismatches and status is not RunStatus.RUNNING:
        failures.append("firmware counters disagree: " + "; ".join(mismatches))
    if error:
        failures.append(error)
    velocity_summary = _velocity_summary(driver, driver.velocity_samples if driver is not None else [])
    for part in ("first_tenth", "last_tenth"):
        for key, value in velocity_summary.get(part, {}).items():
            if key.endswith("_max_error_pct") and value > velocity_summary["goal_max_error_pct"]:
                failures.append(
                    f"velocity estimate: {key.removesuffix('_max_error_pct')} off by {value} % in the "
                    f"{part.replace('_', ' ')}, goal below {velocity_summary['goal_max_error_pct']} %"
                )
    final = status
    if status is not RunStatus.RUNNING:
        if failures:
            final = RunStatus.FAILED
        elif status is RunStatus.INTERRUPTED:
            final = RunStatus.INTERRUPTED
        else:
            final = RunStatus.PASSED
    cycles = driver.cycle if driver is not None else 0
    fw_cpu = [s.cpu_s for s in samples]
    return {
        "status": final.value,
        "failures": failures,
        "cycles_requested": args.cycles,
        "cycles": cycles,
        "lost_cycles": len(lost),
        "lost": [asdict(c) for c in lost[:20]],
        "problems": problem_count,
        "problem_details": problems[:50],
        "faults": {
            "injected_by_kind": dict(driver.faults_done) if driver is not None else {},
            "injected": sum(driver.faults_done.values()) if driver is not None else 0,
            "planned": len(plan.faults),
            "interval": plan.interval,
            "seed": plan.seed,
        },
        "syncs": {
            "operational": tally.syncs_operational,
            "while_stopped": tally.syncs_stopped,
        },
        "frames_filtered": tally.frames_filtered,
        "memory": {
            **asdict(verdict),
            "samples": len(samples),
            "sample_every": args.sample_every,
            "series": [
                [s.cycle, s.vm_rss_kib, s.rss_exact_kib, s.anon_huge_kib, s.fds]
                for s in thin(samples, SERIES_POINTS)
            ],
            "series_columns": ["cycle", "VmRSS KiB", "exact Rss KiB", "AnonHugePages KiB", "fds"],
            "transparent_huge_pages": args.thp,
        },
        "firmware": {
            **firmware,
            "expected_counters": tally.expected_counters(),
            "mismatches": mismatches,
            "cpu_ms_per_cycle": round(1e3 * (fw_cpu[-1] - fw_cpu[0]) / cycles, 4)
            if len(fw_cpu) >= 2 and cycles
            else None,
        },
        "driver": {
            "cpu_ms_per_cycle": round(1e3 * driver_cpu_s / cycles, 4) if cycles else None,
            "pinned_cpu": args.cpu if args.pin else None,
            "heartbeats": tally.heartbeats,
            "heartbeat_states": {
                f"0x{state:02X}": n
                for state, n in sorted((driver.heartbeat_states if driver else {}).items())
            },
            "emcy": [
                f"cycle {c}: 0x{code:04X} about 0x{about:04X}"
                for c, code, about in (driver.emcy_log if driver else [])
            ][:300],
        },
        "velocity": velocity_summary,
        "duration_s": round(duration_s, 1),
        "cycling_s": round(cycling_s, 1) if cycling_s is not None else None,
        "rate_cycles_per_s": round(cycles / cycling_s, 1) if cycling_s else None,
        "started_at": datetime.datetime.fromtimestamp(started_wall, datetime.UTC).isoformat(
            timespec="seconds"
        ),
        "bus": bus,
        "seed": plan.seed,
        "period_us": args.period_us,
    }


def _velocity_summary(driver: SoakDriver | None, samples: list[tuple[int, float, float]]) -> dict[str, Any]:
    """The firmware's velocity estimates against the pattern's exact speeds, in the first and the
    last tenth of the run (issue: numbers that stay right after hours): max error in percent."""
    if driver is None or not samples:
        return {}
    expected = {"motor": driver.pattern.motor_velocity_rad_s, "output": driver.pattern.output_velocity_rad_s}

    def spread(part: list[tuple[int, float, float]]) -> dict[str, float]:
        summary: dict[str, float] = {}
        for position, what in ((1, "motor"), (2, "output")):
            values = [row[position] for row in part if math.isfinite(row[position])]
            if not values:
                continue
            truth = expected[what]
            summary |= {
                f"{what}_min": round(min(values), 6),
                f"{what}_max": round(max(values), 6),
                f"{what}_max_error_pct": round(100 * max(abs(v - truth) for v in values) / truth, 6),
            }
        return summary

    tenth = max(1, len(samples) // 10)
    return {
        "expected_motor_velocity_rad_s": round(expected["motor"], 6),
        "expected_output_velocity_rad_s": round(expected["output"], 6),
        "first_tenth": spread(samples[:tenth]),
        "last_tenth": spread(samples[-tenth:]),
        "samples": len(samples),
        "goal_max_error_pct": 0.1,
    }


def run(args: argparse.Namespace, usage_error: Callable[[str], Any]) -> int:
    """Run the soak; the exit code (0 passed, 1 failed, 130 interrupted)."""
    if args.cycles <= 0:
        return usage_error(f"--cycles: expected > 0, got {args.cycles}")
    if args.cpu is None:
        args.cpu = max(os.sched_getaffinity(0))

    out: Path = args.out.resolve()
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
    driver: SoakDriver | None = None
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
            driver=driver,
            plan=plan,
            status=run_status,
            error=error,
            firmware=firmware_info,
            bus=bus_info,
            started_wall=started_wall,
            duration_s=time.monotonic() - started,
            cycling_s=driver.clock() - driver.started_at
            if driver and driver.started_at is not None
            else None,
            driver_cpu_s=(now.user + now.system) - (cpu_start.user + cpu_start.system),
        )

    print(
        f"soak: {args.cycles} cycles, {len(plan.faults)} faults planned (seed {args.seed}, about one "
        f"per {args.fault_interval} cycles), memory judged from cycle {plan.warmup_cycle}, "
        f"bus {bus_info['path']}",
        flush=True,
    )
    from hilrig.session.builder import SessionConfig, open_session  # the one place a session is assembled

    config = SessionConfig(
        out_dir=out,
        node_id=args.node_id,
        period_us=args.period_us,
        trace=False,
        record=False,
        rig=False,
        host_channel=args.channel,
        executable=args.firmware,
        eds=args.eds,
        boot_timeout_s=BOOT_TIMEOUT_S,
        sdo_timeout_s=RECEIVE_TIMEOUT_S,
        firmware_term_timeout_s=30.0,
    )
    session = None
    fw = None
    try:
        session = open_session(config)
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
        link = session.node.open_link(list(layout.receive_ids))
        driver = SoakDriver(
            link,
            session.node.remote.sdo,
            layout,
            plan,
            period_us=args.period_us,
            liveness=fw.check,
            stop_requested=stop,
            on_progress=lambda p: print(format_progress(p), flush=True),
            on_checkpoint=lambda: write_json_atomic(report_path, report(RunStatus.RUNNING)),
            sample_every=args.sample_every,
        )
        driver.start()
        firmware_info["pid"] = _firmware_pid(fw.process)
        firmware_info["startup_s"] = round(time.monotonic() - started, 1)
        pinned = f", driver and firmware pinned to CPU {args.cpu}" if args.pin else ""
        print(
            f"soak: node 0x{args.node_id:02X} up {firmware_info['startup_s']} s after the start "
            f"(firmware pid {pid}{pinned}); cycling",
            flush=True,
        )
        driver.probe = lambda cycle, elapsed: sample_process(pid, cycle, elapsed)
        driver.run(args.cycles)
        driver.finish()
        if driver.stopped_by_request:
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
    _print_summary(data, report_path)
    if data["status"] == RunStatus.PASSED:
        return 0
    return 130 if data["status"] == RunStatus.INTERRUPTED else 1


def _print_summary(data: dict[str, Any], path: Path) -> None:
    memory = data["memory"]
    faults = data["faults"]
    kinds = ", ".join(f"{k} {v}" for k, v in sorted(faults["injected_by_kind"].items())) or "none"
    lines = [
        f"soak: {data['status'].upper()}: {data['cycles']} cycles in {format_duration(data['duration_s'])} "
        f"({data['rate_cycles_per_s']} cycles/s), lost {data['lost_cycles']}, problems {data['problems']}",
        f"soak: faults {faults['injected']} ({kinds})",
        f"soak: memory: {memory['reason']}"
        + (
            f"; RSS at start {memory['rss_start_kib']} KiB" if memory.get("rss_start_kib") is not None else ""
        ),
        f"soak: firmware: {data['firmware']['stop_line'] or 'no stop line'}",
        "soak: velocity estimate, max error in the first / last tenth: "
        + ", ".join(
            f"{what} {data['velocity'].get('first_tenth', {}).get(f'{what}_max_error_pct')} % / "
            f"{data['velocity'].get('last_tenth', {}).get(f'{what}_max_error_pct')} %"
            for what in ("motor", "output")
        ),
        f"soak: bus: {data['bus'].get('path')} (namespace {data['bus'].get('namespace')})",
    ]
    lines += [f"soak: FAILED: {failure}" for failure in data["failures"]]
    lines += [f"soak:   {detail}" for detail in data["problem_details"][:10]]
    lines.append(f"soak: report {path}")
    print("\n".join(lines), flush=True)
