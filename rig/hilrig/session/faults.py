"""Fault injection, scriptable from a scenario and from the command line.

A fault is written `KIND[:TARGET][=VALUE]@START[+DURATION]` (times in seconds of simulation
time in lockstep, wall seconds in real time; without +DURATION a lasting fault lasts to the end):

    drop:motor_encoder_counts@0.5+0.2     the sensor frame carrying it is not sent (or drop:rpdo2)
    delay:thermistor_adc=5@1+0.5          that sensor's value goes out 5 cycles late
    freeze:output_encoder_counts@1        that sensor's value stays what it was at t = 1 s
    offset:motor_current_adc=-300@1+1     raw counts added (encoders wrap, ADCs saturate)
    raw:thermistor_adc=5000@1+0.1         a raw value forced, even one real hardware cannot give
    malformed:length@1                    one sensor frame a byte short (CiA 301: length error)
    malformed:cob-id@1                    one frame on a COB-ID nobody uses (0x7E0)
    flood=2000@1+0.5                      2000 frames/s of the bus's highest priority (0x001;
                                          flood:0x7F0=2000 for another ID), paced per cycle
    kill@2                                SIGKILL the firmware (the rig then reports it)
    restart@2                             SIGKILL, start it again, wait for boot-up, operational
    nmt-stop@1+0.005                      NMT stop (the node must ignore SYNCs), start again after
    sdo-read:gear_ratio@1                 an SDO upload between two cycles (a second master's)

    plan = FaultPlan.parse(["drop:motor_encoder_counts@0.5+0.2", "kill@2"])
    FaultInjector(rig, plan, firmware=firmware).install()
    rig.run(seconds=3)

Sensor faults compose in the order given; each injected start and end goes to the trace as a
warning under /events/faults and into `FaultInjector.log`.
"""

from __future__ import annotations

import collections
import dataclasses
import enum
import math
import re
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from hilrig.errors import RigError
from hilrig.plants.sensors import _WIRE_RANGES, RawSensors

if TYPE_CHECKING:
    from hilrig.engine.rig import Rig
    from hilrig.session.firmware import Firmware

FAULT_EVENTS_PATH = "/events/faults"
UNUSED_COB_ID = 0x7E0
"""A COB-ID no CiA 301 service of the predefined connection set uses (LSS is 0x7E4/0x7E5)."""
DEFAULT_FLOOD_COB_ID = 0x001
"""The highest priority a frame can have after NMT: what a babbling node does to a bus."""
WRAPPING_SENSORS = ("motor_encoder_counts", "output_encoder_counts")
"""Counters that wrap at 2^16 (an offset wraps them, as a real encoder's counter would)."""


class FaultSpecError(RigError, ValueError):
    """A fault description that cannot be used; the message says what to write instead."""


class FaultKind(enum.StrEnum):
    DROP = "drop"
    DELAY = "delay"
    FREEZE = "freeze"
    OFFSET = "offset"
    RAW = "raw"
    MALFORMED = "malformed"
    FLOOD = "flood"
    KILL = "kill"
    RESTART = "restart"
    NMT_STOP = "nmt-stop"
    SDO_READ = "sdo-read"


SENSOR_VALUE_KINDS = (FaultKind.DELAY, FaultKind.FREEZE, FaultKind.OFFSET, FaultKind.RAW)
"""Faults that change a sensor's value in the frame the rig sends."""
ONE_SHOT_KINDS = (FaultKind.MALFORMED, FaultKind.KILL, FaultKind.RESTART, FaultKind.SDO_READ)
"""Faults that happen once, at START (a +DURATION makes no sense for them)."""
MALFORMED_TARGETS = ("length", "cob-id")

FAULT_SYNTAX_HELP = (
    "KIND[:TARGET][=VALUE]@START[+DURATION], times in seconds. Kinds: "
    "drop:SENSOR|rpdoN (frames not sent), delay:SENSOR=CYCLES, freeze:SENSOR, "
    "offset:SENSOR=COUNTS, raw:SENSOR=COUNTS (out-of-range allowed), "
    "malformed:length|cob-id (one frame), flood[:COB_ID]=FRAMES_PER_S, kill, restart, "
    "nmt-stop (+DURATION: start again after), sdo-read:FIELD (one SDO upload)"
)

_SPEC = re.compile(
    r"^(?P<kind>[a-z-]+)(?::(?P<target>[A-Za-z0-9_-]+))?(?:=(?P<value>[^@]+))?"
    r"@(?P<start>[^+]+)(?:\+(?P<duration>.+))?$"
)


@dataclass(frozen=True)
class FaultSpec:
    """One fault: what, on what, how much, from when, for how long (None: to the end)."""

    kind: FaultKind
    start_s: float
    target: str | None = None
    value: float | None = None
    duration_s: float | None = None

    @property
    def end_s(self) -> float | None:
        return None if self.duration_s is None else self.start_s + self.duration_s

    def __str__(self) -> str:
        text = self.kind.value
        if self.target is not None:
            text += f":{self.target}"
        if self.value is not None:
            text += f"={self.value:g}"
        text += f"@{self.start_s:g}"
        if self.duration_s is not None:
            text += f"+{self.duration_s:g}"
        return text

    @classmethod
    def parse(cls, text: str) -> FaultSpec:
        """A FaultSpec from its command-line form; FaultSpecError says what is wrong."""
        match = _SPEC.match(text.strip())
        if match is None:
            raise FaultSpecError(f"fault {text!r}: expected {FAULT_SYNTAX_HELP}")
        try:
            kind = FaultKind(match["kind"])
        except ValueError:
            kinds = ", ".join(k.value for k in FaultKind)
            raise FaultSpecError(f"fault {text!r}: unknown kind {match['kind']!r}; kinds: {kinds}") from None
        start = _seconds(text, "start", match["start"])
        duration = _seconds(text, "duration", match["duration"]) if match["duration"] else None
        if duration is not None and duration <= 0:
            raise FaultSpecError(f"fault {text!r}: duration must be > 0, got {duration:g}")
        value = _number(text, match["value"]) if match["value"] is not None else None
        spec = cls(kind=kind, start_s=start, target=match["target"], value=value, duration_s=duration)
        spec.check()
        return spec

    def check(self) -> None:
        """Raise FaultSpecError if target, value or duration do not fit the kind."""
        where = f"fault {self}"
        kind = self.kind
        if kind in ONE_SHOT_KINDS and self.duration_s is not None:
            raise FaultSpecError(f"{where}: {kind} happens once, at its start; drop the +DURATION")
        if kind in (FaultKind.DROP, *SENSOR_VALUE_KINDS):
            sensors = ", ".join(_WIRE_RANGES)
            if self.target is None:
                raise FaultSpecError(
                    f"{where}: name the sensor, e.g. {kind}:thermistor_adc; sensors: {sensors}"
                )
            is_rpdo = re.fullmatch(r"rpdo[1-9]", self.target) is not None
            if self.target not in _WIRE_RANGES and not (kind is FaultKind.DROP and is_rpdo):
                hint = " or rpdoN" if kind is FaultKind.DROP else ""
                raise FaultSpecError(f"{where}: unknown sensor {self.target!r}; sensors: {sensors}{hint}")
        needs_value = {
            FaultKind.DELAY: "the delay in cycles",
            FaultKind.OFFSET: "the raw counts to add",
            FaultKind.RAW: "the raw value to send",
            FaultKind.FLOOD: "the rate in frames per second",
        }
        if kind in needs_value and self.value is None:
            raise FaultSpecError(f"{where}: give {needs_value[kind]} with =VALUE")
        if kind not in needs_value and self.value is not None:
            raise FaultSpecError(f"{where}: {kind} takes no =VALUE")
        if kind in (FaultKind.DELAY, FaultKind.OFFSET, FaultKind.RAW) and self.value != int(self.value or 0):
            raise FaultSpecError(f"{where}: {kind} needs a whole number, got {self.value:g}")
        if kind is FaultKind.DELAY and (self.value or 0) < 1:
            raise FaultSpecError(f"{where}: the delay must be at least 1 cycle")
        if kind is FaultKind.RAW and self.target in _WIRE_RANGES:
            low, high = _WIRE_RANGES[self.target]
            if not low <= int(self.value or 0) <= high:
                raise FaultSpecError(
                    f"{where}: {self.target} travels as {low}..{high}; {self.value:g} cannot be sent"
                )
        if kind is FaultKind.FLOOD:
            if (self.value or 0) <= 0:
                raise FaultSpecError(f"{where}: the flood rate must be > 0 frames/s")
            if self.target is not None:
                _cob_id(where, self.target)
        if kind is FaultKind.MALFORMED and self.target not in MALFORMED_TARGETS:
            raise FaultSpecError(f"{where}: say which: malformed:length or malformed:cob-id")
        if kind in (FaultKind.KILL, FaultKind.RESTART, FaultKind.NMT_STOP) and self.target is not None:
            raise FaultSpecError(f"{where}: {kind} takes no :TARGET")
        if kind is FaultKind.SDO_READ and self.target is None:
            raise FaultSpecError(f"{where}: name the object to read, e.g. sdo-read:gear_ratio")

    @property
    def flood_cob_id(self) -> int:
        return _cob_id(f"fault {self}", self.target) if self.target else DEFAULT_FLOOD_COB_ID


def _seconds(text: str, what: str, value: str) -> float:
    seconds = _number(text, value)
    if not math.isfinite(seconds) or seconds < 0:
        raise FaultSpecError(f"fault {text!r}: {what} must be a time >= 0 in seconds, got {value}")
    return seconds


def _number(text: str, value: str) -> float:
    try:
        return float(int(value, 0)) if re.fullmatch(r"[+-]?0[xX][0-9a-fA-F]+", value) else float(value)
    except ValueError:
        raise FaultSpecError(f"fault {text!r}: {value!r} is not a number") from None


def _cob_id(where: str, text: str) -> int:
    try:
        cob_id = int(text, 0)
    except ValueError:
        raise FaultSpecError(
            f"{where}: the flood's COB-ID must be a number like 0x001, got {text!r}"
        ) from None
    if not 0x001 <= cob_id <= 0x7FF:
        raise FaultSpecError(f"{where}: COB-ID 0x{cob_id:X} is outside 0x001..0x7FF (0x000 is NMT)")
    return cob_id


@dataclass(frozen=True)
class FaultPlan:
    """Faults for one run, in the order given (sensor faults compose in this order)."""

    faults: tuple[FaultSpec, ...] = ()

    @classmethod
    def parse(cls, texts: Iterable[str]) -> FaultPlan:
        return cls(tuple(FaultSpec.parse(text) for text in texts))

    def __bool__(self) -> bool:
        return bool(self.faults)


@dataclass(frozen=True)
class FaultEvent:
    """What the injector did, when."""

    time_s: float
    cycle: int
    text: str


class _ActiveSensorFault:
    """A sensor value fault while it is on; `apply` maps the physics' value to the sent one."""

    def __init__(self, spec: FaultSpec, history: collections.deque[int] | None) -> None:
        self.spec = spec
        self.frozen: int | None = None
        self.history = history  # delay: the physics' latest values of this sensor

    def apply(self, value: int) -> int:
        spec = self.spec
        assert spec.target is not None
        low, high = _WIRE_RANGES[spec.target]
        if spec.kind is FaultKind.FREEZE:
            if self.frozen is None:
                self.frozen = value
            return self.frozen
        if spec.kind is FaultKind.RAW:
            return int(spec.value or 0)
        if spec.kind is FaultKind.OFFSET:
            shifted = value + int(spec.value or 0)
            if spec.target in WRAPPING_SENSORS:
                return shifted % (high + 1)
            return min(high, max(low, shifted))
        if spec.kind is FaultKind.DELAY:
            assert self.history is not None
            # history[-1] is this cycle's value; N cycles late is history[-1 - N], or the
            # oldest there is while the delay line fills up.
            delay = int(spec.value or 0)
            return self.history[max(0, len(self.history) - 1 - delay)]
        raise AssertionError(spec.kind)


class FaultInjector:
    """Carries out a FaultPlan on a Rig: sensor faults through the rig's sensor override,
    dropped frames by pausing RPDOs, raw frames on the rig's bus, kill/restart on `firmware`.

    Call `install()` before running; events fire at their simulation times (`rig.at`).
    """

    def __init__(
        self,
        rig: Rig,
        plan: FaultPlan | Sequence[FaultSpec],
        *,
        firmware: Firmware | None = None,
        boot_timeout_s: float = 60.0,
        on_event: Callable[[FaultEvent], None] | None = None,
    ) -> None:
        self.rig = rig
        self.faults = plan.faults if isinstance(plan, FaultPlan) else tuple(plan)
        self.firmware = firmware
        self.boot_timeout_s = boot_timeout_s
        self.on_event = on_event
        self.log: list[FaultEvent] = []
        self.frames_sent: dict[str, int] = collections.Counter()
        self._active: list[_ActiveSensorFault] = []
        self._delay_lines: dict[str, collections.deque[int]] = {}
        self._floods: dict[FaultSpec, float] = {}  # active flood -> fractional frames owed
        self._installed = False

    # --- Setup --------------------------------------------------------------------------
    def install(self) -> None:
        """Check the plan against the rig and schedule every start and end."""
        if self._installed:
            raise RuntimeError("FaultInjector.install() called twice")
        rig = self.rig
        for spec in self.faults:
            self._check_against_rig(spec)
            rig.at(spec.start_s, lambda _rig, spec=spec: self._start(spec))
            if spec.end_s is not None:
                rig.at(spec.end_s, lambda _rig, spec=spec: self._end(spec))
            if spec.kind is FaultKind.DELAY:
                assert spec.target is not None
                length = max(int(spec.value or 0) + 1, len(self._delay_lines.get(spec.target, ())))
                self._delay_lines[spec.target] = collections.deque(maxlen=length)
        if any(spec.kind in SENSOR_VALUE_KINDS for spec in self.faults):
            rig.override_sensors(self._override)
        if any(spec.kind is FaultKind.FLOOD for spec in self.faults):
            rig.before_each_cycle(self._flood_cycle)
        self._installed = True

    def _check_against_rig(self, spec: FaultSpec) -> None:
        rig = self.rig
        where = f"fault {spec}"
        if spec.kind in (FaultKind.KILL, FaultKind.RESTART) and self.firmware is None:
            raise FaultSpecError(f"{where}: the rig does not own the firmware process here (a real board?)")
        if spec.kind in (FaultKind.DROP, *SENSOR_VALUE_KINDS) and not rig.physics:
            raise FaultSpecError(f"{where}: without physics the rig sends no sensor frames")
        if spec.kind is FaultKind.DROP:
            self._rpdo_number(spec)  # raises if nothing carries it
        if spec.kind is FaultKind.SDO_READ:
            assert spec.target is not None
            try:
                rig.check_names(spec.target)
            except KeyError as error:
                raise FaultSpecError(f"{where}: {error}") from None

    def _rpdo_number(self, spec: FaultSpec) -> int:
        assert spec.target is not None
        rpdos = self.rig.node.rpdos
        if spec.target.startswith("rpdo"):
            number = int(spec.target[4:])
            if number not in rpdos or not rpdos[number].enabled:
                raise FaultSpecError(f"fault {spec}: the node has no enabled RPDO{number}")
            return number
        for number, pdo in rpdos.items():
            if pdo.enabled and spec.target in pdo.names:
                return number
        raise FaultSpecError(f"fault {spec}: no enabled RPDO carries {spec.target}")

    # --- Events -------------------------------------------------------------------------
    def _record(self, text: str) -> None:
        event = FaultEvent(time_s=self.rig.t, cycle=self.rig.cycle, text=text)
        self.log.append(event)
        self.rig.log_event(FAULT_EVENTS_PATH, f"fault injected: {text}")
        if self.on_event is not None:
            self.on_event(event)

    def _start(self, spec: FaultSpec) -> None:
        kind = spec.kind
        if kind is FaultKind.DROP:
            number = self._rpdo_number(spec)
            self.rig.pause_rpdo(number)
            self._record(f"{spec}: RPDO{number} frames not sent")
        elif kind in SENSOR_VALUE_KINDS:
            history = self._delay_lines.get(spec.target or "") if kind is FaultKind.DELAY else None
            self._active.append(_ActiveSensorFault(spec, history))
            self._record(f"{spec}: {spec.target} {_describe_value_fault(spec)}")
        elif kind is FaultKind.MALFORMED:
            self._send_malformed(spec)
        elif kind is FaultKind.FLOOD:
            self._floods[spec] = 0.0
            self._record(f"{spec}: {spec.value:g} frames/s on 0x{spec.flood_cob_id:03X}")
        elif kind is FaultKind.KILL:
            assert self.firmware is not None
            self.firmware.kill()
            self._record(f"{spec}: firmware killed with SIGKILL")
        elif kind is FaultKind.RESTART:
            assert self.firmware is not None
            self._record(f"{spec}: firmware killed with SIGKILL, restarting")
            self.rig.restart_node(self.firmware.restart, boot_timeout_s=self.boot_timeout_s)
            self._record(f"{spec}: firmware booted again and is operational")
        elif kind is FaultKind.NMT_STOP:
            from boardproto.cia301 import NmtCommand

            self.rig.nmt(NmtCommand.STOP)
            self._record(f"{spec}: NMT stop sent (SYNCs go unanswered)")
        elif kind is FaultKind.SDO_READ:
            assert spec.target is not None
            value = self.rig.read(spec.target)
            self._record(f"{spec}: {spec.target} read by SDO: {value}")

    def _end(self, spec: FaultSpec) -> None:
        if spec.kind is FaultKind.DROP:
            number = self._rpdo_number(spec)
            if not any(
                f.kind is FaultKind.DROP
                and f is not spec
                and self._covers(f)
                and self._rpdo_number(f) == number
                for f in self.faults
            ):
                self.rig.resume_rpdo(number)
        elif spec.kind in SENSOR_VALUE_KINDS:
            self._active = [active for active in self._active if active.spec is not spec]
        elif spec.kind is FaultKind.FLOOD:
            self._floods.pop(spec, None)
        elif spec.kind is FaultKind.NMT_STOP:
            from boardproto.cia301 import NmtCommand

            self.rig.nmt(NmtCommand.START)
        self._record(f"{spec}: ended")

    def _covers(self, spec: FaultSpec) -> bool:
        """Whether `spec` is on at rig.t (started, not yet ended)."""
        now = self.rig.t
        return spec.start_s <= now + 1e-9 and (spec.end_s is None or now + 1e-9 < spec.end_s)

    # --- Per cycle ----------------------------------------------------------------------
    def _override(self, raw: RawSensors) -> RawSensors:
        for name, line in self._delay_lines.items():
            line.append(getattr(raw, name))
        if not self._active:
            return raw
        values = raw.as_dict()
        physics = dict(values)
        for active in self._active:
            name = active.spec.target
            assert name is not None
            # A delay replays the physics' own past values; other faults act on what the
            # faults before them in the plan left.
            source = physics[name] if active.spec.kind is FaultKind.DELAY else values[name]
            values[name] = active.apply(source)
        return dataclasses.replace(raw, **values)

    def _flood_cycle(self, rig: Rig) -> None:
        for spec, owed in list(self._floods.items()):
            owed += (spec.value or 0.0) * rig.period_s
            count = int(owed)
            self._floods[spec] = owed - count
            for _ in range(count):
                rig.send_frame(spec.flood_cob_id, bytes(8))
            self.frames_sent["flood"] += count

    def _send_malformed(self, spec: FaultSpec) -> None:
        rig = self.rig
        if spec.target == "length":
            enabled = [p for p in rig.node.rpdos.values() if p.enabled and p.names]
            sensors = [p for p in enabled if any(rig.table.is_hil_input(n) for n in p.names)]
            pdo = (sensors or enabled)[0]
            length = pdo.length
            rig.send_frame(pdo.cob_id, bytes(max(0, length - 1)))
            self._record(f"{spec}: {pdo.label} sent with {length - 1} bytes, not {length}")
        else:
            rig.send_frame(UNUSED_COB_ID, bytes(8))
            self._record(f"{spec}: a frame on unused COB-ID 0x{UNUSED_COB_ID:03X}")
        self.frames_sent["malformed"] += 1


def _describe_value_fault(spec: FaultSpec) -> str:
    if spec.kind is FaultKind.DELAY:
        return f"sent {spec.value:g} cycles late"
    if spec.kind is FaultKind.FREEZE:
        return "frozen at its present value"
    if spec.kind is FaultKind.OFFSET:
        return f"offset by {spec.value:+g} counts"
    return f"forced to raw {spec.value:g}"


__all__ = [
    "FAULT_EVENTS_PATH",
    "FAULT_SYNTAX_HELP",
    "FaultEvent",
    "FaultInjector",
    "FaultKind",
    "FaultPlan",
    "FaultSpec",
    "FaultSpecError",
]
