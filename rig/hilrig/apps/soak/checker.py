"""The soak's judge of every cycle the engine runs: the checks against what the injected faults
imply (the status TPDO, the EMCYs), the lost cycles and problems, and the tally of what went on
the bus and came back, which the firmware's stop line must agree with.

It runs nothing itself: the engine's lockstep driver (`hilrig.engine.lockstep`) sends the RPDOs
and SYNC and collects the TPDOs due at it, hands each refused frame and each cycle it gave up on
to `on_problem`, and the node's EMCY and heartbeat frames to `on_emcy` / `on_heartbeat` as they
arrive; the soak (`hilrig.apps.soak.soak`) then calls `operational_cycle` with each result.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass

from boardproto.cia301 import HEARTBEAT_STATE_MASK, split_emcy
from hilrig.apps.soak.layout import STALE_ENCODER_FLAGS, SoakLayout
from hilrig.engine.driver import CycleResult
from hilrig.engine.lockstep import CycleProblem
from hilrig.errors import RigError
from hilrig.wire.node import emcy_object_index
from hilrig.wire.transport import PdoLayout, Value

DEFAULT_MAX_LOST = 10
"""Give up after this many lost cycles (the verdict is already "failed" at the first one)."""
MAX_PROBLEM_TEXTS = 100
MAX_EMCY_LOG = 1000

Emcy = tuple[int, int]
"""(error code, the object index the board names)."""


class SoakError(RigError, RuntimeError):
    """The soak could not go on (the firmware stopped answering, too many lost cycles)."""


@dataclass
class Tally:
    """What the soak put on the bus and got back; the firmware's stop line must agree."""

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


@dataclass(frozen=True)
class LostCycle:
    cycle: int
    sync_counter: int
    missing: tuple[str, ...]
    received: tuple[str, ...]
    late: tuple[str, ...] = ()


class CycleChecker:
    """Checks each cycle's result against the faults' expectations and keeps the tally.

    `cycle` is the soak's count of firmware cycles (SYNCs while operational), which the problem
    texts and the EMCY log are stamped with; the soak sets it before each cycle runs."""

    def __init__(self, layout: SoakLayout, *, max_lost: int = DEFAULT_MAX_LOST) -> None:
        self.layout = layout
        self.max_lost = max_lost
        self.tally = Tally()
        self.cycle = 0
        self.lost: list[LostCycle] = []
        self.problems: list[str] = []
        self.problem_count = 0
        self.emcy_log: list[tuple[int, int, int]] = []
        """(cycle, code, about) of every EMCY, for the report (a few hundred at most)."""
        self.heartbeat_states: Counter[int] = Counter()
        self.velocity: tuple[Value, ...] | None = None
        """The latest values of the TPDO carrying motor_velocity (None before it came)."""
        self.velocity_tpdo: PdoLayout | None = next(
            (p for p in layout.tpdos if "motor_velocity" in p.names), None
        )
        self._velocity_cob = self.velocity_tpdo.cob_id if self.velocity_tpdo is not None else -1
        self._status_cob = layout.status.cob_id
        self._healthy_status = self.status_values(0)
        self.latched_status = self.status_values(STALE_ENCODER_FLAGS)
        """The status TPDO's values while the stale-sensor fault holds its latch."""
        self._cycle_emcy: list[Emcy] = []
        self.lost_problem: CycleProblem | None = None
        """The problem of the cycle just run when the driver gave up on its due TPDOs: the soak
        resynchronises, then calls `lost_cycle` (and sets this back to None)."""

    def status_values(self, fault_flags: int) -> tuple[Value, ...]:
        """The status TPDO's values (as the exchange decodes them) for a latched fault mask."""
        return self.layout.status.unpack(self.layout.status_bytes(fault_flags))

    # --- What the engine hands over ----------------------------------------------------
    def on_emcy(self, _cob_id: int, data: bytes) -> None:
        """An EMCY frame (a listener on the driver's link): kept for this cycle's check."""
        parts = split_emcy(data)
        about = emcy_object_index(parts.manufacturer)
        self.tally.emcy_received += 1
        self._cycle_emcy.append((parts.code, about))
        if len(self.emcy_log) < MAX_EMCY_LOG:
            self.emcy_log.append((self.cycle, parts.code, about))

    def on_heartbeat(self, _cob_id: int, data: bytes) -> None:
        self.tally.heartbeats += 1
        if data:
            self.heartbeat_states[data[0] & HEARTBEAT_STATE_MASK] += 1

    def on_problem(self, problem: CycleProblem) -> None:
        """A frame the driver refused (a TPDO the node sent, counted), or due TPDOs it gave up
        on (`lost_problem`)."""
        if problem.missing:
            self.lost_problem = problem
            return
        self.tally.tpdos_received += 1
        self.problem(problem.what)

    # --- One cycle ----------------------------------------------------------------------
    def operational_cycle(
        self,
        result: CycleResult,
        status: tuple[Value, ...] | None = None,
        emcy: Sequence[Emcy] = (),
    ) -> None:
        """Check a cycle run while the node was operational: `status` is the status TPDO's
        values the injected faults imply (default: no fault), `emcy` the EMCYs it must bring
        (default: none)."""
        got = result.values_by_cob_id()
        tally = self.tally
        tally.syncs_operational += 1
        tally.frames_sent += len(result.sent_rows) + 1  # its RPDOs and the SYNC
        tally.tpdos_received += len(got)
        values = got.get(self._status_cob)
        if values is not None and values != (self._healthy_status if status is None else status):
            self._status_problem(values, self._healthy_status if status is None else status)
        velocity = got.get(self._velocity_cob)
        if velocity is not None:
            self.velocity = velocity
        if self._cycle_emcy or emcy:
            self.check_emcy(emcy)

    def stopped_cycle(self, result: CycleResult) -> None:
        """A cycle run while the node was stopped: its RPDOs and SYNC must be ignored (a TPDO
        it answers with anyway is refused: `on_problem`)."""
        frames = len(result.sent_rows) + 1
        tally = self.tally
        tally.frames_sent += frames
        tally.ignored_expected += frames
        tally.syncs_stopped += 1
        tally.tpdos_received += len(result.values_by_cob_id())  # event-driven ones, if any

    def _status_problem(self, got: tuple[Value, ...], want: tuple[Value, ...]) -> None:
        names = self.layout.status.names
        self.problem(
            f"{self.layout.status.label}: expected {dict(zip(names, want, strict=True))}, "
            f"got {dict(zip(names, got, strict=True))}"
        )

    def check_emcy(self, expected: Sequence[Emcy]) -> None:
        """The EMCYs since the last check must be exactly `expected` (in any order)."""
        got, self._cycle_emcy = self._cycle_emcy, []
        if sorted(got) != sorted(expected):
            words = ", ".join(f"0x{code:04X} about 0x{about:04X}" for code, about in got) or "none"
            wanted = ", ".join(f"0x{code:04X} about 0x{about:04X}" for code, about in expected) or "none"
            self.problem(f"EMCY: expected {wanted}, got {words}")

    @property
    def emcy_pending(self) -> bool:
        return bool(self._cycle_emcy)

    def problem(self, text: str) -> None:
        self.problem_count += 1
        if len(self.problems) < MAX_PROBLEM_TEXTS:
            self.problems.append(f"cycle {self.cycle}: {text}")

    # --- Lost cycles --------------------------------------------------------------------
    def lost_cycle(self, problem: CycleProblem, sync_counter: int, late: Sequence[PdoLayout]) -> None:
        """Record a lost cycle, with the TPDOs that came late (after the resynchronising SDO
        round trip); SoakError past `max_lost`."""
        self.lost_problem = None
        self.tally.tpdos_received += len(late)
        labels = tuple(p.label for p in late)
        self.lost.append(
            LostCycle(
                self.cycle,
                sync_counter,
                tuple(p.label for p in problem.missing),
                tuple(p.label for p in problem.received),
                labels,
            )
        )
        self.problem(f"lost: {problem.what}" + (f" (late: {', '.join(labels)})" if labels else ""))
        if len(self.lost) > self.max_lost:
            raise SoakError(
                f"{len(self.lost)} lost cycles (limit {self.max_lost}); last at cycle {self.cycle}"
            )
