"""The lockstep driver on a bus with a bit rate (`hilrig.wire.bustime`): what of each cycle's
frames the real bus carries in the cycle, and what reaches the node or the plant later.

Each cycle, before anything is sent, the cycle's frames go to the timed bus by their worst-case
lengths: the rig's RPDOs, its SYNC, the node's TPDOs due at that SYNC (by their mapping's
length), the node's heartbeat when its producer time comes round. Then:

- an RPDO that does not fit is not sent this cycle: it goes to the node in the cycle the bus
  has room for it, so the node sees it late (its RPDO deadline monitoring and the stale-sensor
  rules react as they would on the bench);
- the node still sends every due TPDO at once (it cannot know better), but one that does not
  fit is taken back out of the cycle: the plant and the history (what a scenario asserts on)
  get it in the cycle the bus delivers it, as if it had arrived then;
- the SYNC is always sent: it has the bus's highest priority;
- the frames the rig learns of only after a cycle's schedule (`charge`) take the next cycle's
  bus time, in their turn: an EMCY the node sent (the rig has it at once: its identifier loses
  arbitration only to the SYNC), and an SDO transfer's requests and answers, which happen
  between two cycles. The master waits for the bus to carry them (`Rig` runs cycles until
  `sdo_waiting` is 0): a late SDO answer is late for the master as on a real bus. The node
  acts on the request when it comes (between the cycles): the one thing still ideal about SDO.

`BusTimeline` keeps, per cycle, the bus's real load (at most 100 %), the backlog and every late
frame, for the trace and for a scenario's assertions.
"""

from __future__ import annotations

from array import array
from collections.abc import Callable
from dataclasses import dataclass, field

from canopen.sdo import SdoClient

from boardproto.cia301 import SYNC_COB_ID, heartbeat_cob_id
from hilrig.engine.history import PdoRow, Value
from hilrig.wire.bustime import BusFrame, TimedBus, bitrate_text
from hilrig.wire.transport import CAN_FRAME_SIZE, CAN_HEADER, PdoLayout

_SYNC_DLC = 1
_HEARTBEAT_DLC = 1
_SDO = "sdo"  # the payload of an SDO transfer's frame: the master waits for it
SDO_ANSWER_TIMEOUT_S = SdoClient.RESPONSE_TIMEOUT
"""How long, in simulation time, the master waits on the timed bus for its SDO transfer's next
frame to get on the bus: canopen's own default response timeout (its class attribute; the
session's `sdo_timeout_s` is a wall-clock hang guard)."""
_TPDO = "tpdo"  # a due TPDO's payload until its data came: a placeholder


@dataclass(frozen=True, slots=True)
class LateFrame:
    """A frame the bus delivered `late` cycles after the cycle it was queued in (`origin`)."""

    cycle: int
    cob_id: int
    origin: int

    @property
    def late(self) -> int:
        return self.cycle - self.origin


@dataclass
class BusTimeline:
    """Per cycle of a run on the timed bus: the bus's load (0..1) and the frames waiting after
    it; and every frame that was delivered late."""

    first_cycle: int = 0
    """The cycle of `load[0]` and `backlog_frames[0]`: one entry per cycle from there on."""
    load: array = field(default_factory=lambda: array("d"))
    backlog_frames: array = field(default_factory=lambda: array("q"))
    late_frames: array = field(default_factory=lambda: array("q"))
    """Per cycle: frames of earlier cycles it delivered."""
    late: list[LateFrame] = field(default_factory=list)
    replaced: dict[int, int] = field(default_factory=dict)
    """COB-ID -> frames of it never sent: a newer one came while they waited."""
    waiting: tuple[int, ...] = ()
    """COB-IDs of the frames waiting after the last cycle, in arbitration order."""

    def cycles(self) -> range:
        """The cycles `load` and `backlog_frames` are of."""
        return range(self.first_cycle, self.first_cycle + len(self.load))

    def late_of(self, cob_id: int) -> list[LateFrame]:
        return [f for f in self.late if f.cob_id == cob_id]

    @property
    def peak_backlog(self) -> int:
        return max(self.backlog_frames, default=0)

    def describe(self, bitrate: int) -> str:
        """'1 Mbit/s: load 100 % mean, 100 % peak; 14 frames late: 0x3D0 x 14 (up to 3 cycles);
        never sent (...): 0x490 x 50; backlog up to 2 frames' (one line: summaries, failures)."""
        load = self.load
        mean = 100.0 * sum(load) / len(load) if load else 0.0
        text = f"{bitrate_text(bitrate)}: load {mean:.0f} % mean, {100.0 * max(load, default=0.0):.0f} % peak"
        if not self.late and not self.peak_backlog:
            return text + "; no frame late"
        by_cob: dict[int, list[int]] = {}
        for frame in self.late:
            by_cob.setdefault(frame.cob_id, []).append(frame.late)
        worst = sorted(by_cob.items(), key=lambda item: -len(item[1]))
        parts = ", ".join(
            f"0x{cob_id:03X} x {len(lates)} (up to {max(lates)} cycles)" for cob_id, lates in worst
        )
        lost = ", ".join(f"0x{cob_id:03X} x {count}" for cob_id, count in sorted(self.replaced.items()))
        waiting = ", ".join(f"0x{cob_id:03X}" for cob_id in self.waiting) or "none"
        return (
            f"{text}; {len(self.late)} frames late{': ' + parts if parts else ''}; never sent (a newer "
            f"one came first): {lost or 'none'}; backlog up to {self.peak_backlog} frames, waiting "
            f"at the end: {waiting}"
        )


class BusTiming:
    """The timed bus of one lockstep driver (node): `plan` before a cycle's frames go out,
    `deliver` after its exchange. `heartbeat_every`: the node's heartbeat producer time in
    cycles (0: none)."""

    def __init__(
        self,
        bus: TimedBus,
        tpdos: dict[int, PdoLayout],
        node_id: int,
        heartbeat_every: int = 0,
        first_cycle: int = 0,
    ) -> None:
        self.bus = bus
        self.timeline = BusTimeline(first_cycle)
        self._tpdos = tpdos
        self._heartbeat = heartbeat_cob_id(node_id)
        self._heartbeat_every = heartbeat_every
        self._late_tpdos: dict[int, BusFrame] = {}  # this cycle's due TPDOs that wait
        self._delivered_tpdos: list[BusFrame] = []  # earlier cycles' TPDOs delivered this cycle
        self._charged: list[BusFrame] = []  # frames for the next cycle's time (`charge`)
        self._next = first_cycle  # the cycle whose time a frame charged now takes
        self.sdo_waiting = 0
        """SDO frames charged that the bus has not carried yet (the master waits for them)."""
        self.sdo_delivered = 0
        """SDO frames the bus carried so far (a master's wait sees progress in it)."""

    def charge(self, cob_id: int, dlc: int, *, sdo: bool = False) -> None:
        """A frame on the bus that the cycle's schedule did not know of: an EMCY the node sent,
        an SDO request or answer (`sdo`: counted in `sdo_waiting` until the bus carries it). It
        takes bus time from the next cycle on, in its arbitration turn."""
        self._charged.append(BusFrame(cob_id, dlc, self._next, _SDO if sdo else None, queued=True))
        if sdo:
            self.sdo_waiting += 1

    def drop_sdo(self) -> None:
        """The master gave up on its SDO transfer: its frames still waiting leave the bus."""
        self._charged = [f for f in self._charged if f.payload is not _SDO]
        self.bus.backlog = [f for f in self.bus.backlog if f.payload is not _SDO]
        self.sdo_waiting = 0

    def plan(
        self, n: int, due: frozenset[int], sent: tuple[PdoRow, ...], frames: bytes
    ) -> tuple[tuple[PdoRow, ...], bytes]:
        """Cycle `n`'s time on the bus: the RPDO rows and frames (joined) to send to the node
        now: the ones of `sent`/`frames` that fit, and earlier ones whose turn came."""
        bus = self.bus
        heartbeat = bool(self._heartbeat_every) and n % self._heartbeat_every == 0
        timeline = self.timeline
        self._late_tpdos.clear()
        self._delivered_tpdos.clear()
        self._next = n + 1
        charged, self._charged = self._charged, []
        # The cycle's shape: its due TPDOs, whether a heartbeat falls in it, and its RPDOs'
        # headers (identifier bytes and data length of each 16-byte frame).
        shape = (
            due,
            heartbeat,
            frames[0::CAN_FRAME_SIZE],
            frames[1::CAN_FRAME_SIZE],
            frames[4::CAN_FRAME_SIZE],
        )
        bits = None if charged else bus.fits_cached(shape, lambda: self._frames_of(due, heartbeat, frames))
        if bits is not None:  # nothing waiting, and all of it fits: the ideal bus's cycle
            timeline.waiting = ()
            timeline.load.append(bits / bus.window_bits)
            timeline.backlog_frames.append(0)
            timeline.late_frames.append(0)
            return sent, frames
        queued = [BusFrame(SYNC_COB_ID, _SYNC_DLC, n)]
        for i, at in enumerate(range(0, len(frames), CAN_FRAME_SIZE)):
            cob_id, dlc = CAN_HEADER.unpack_from(frames, at)
            queued.append(BusFrame(cob_id, dlc, n, (frames[at : at + CAN_FRAME_SIZE], sent[i])))
        queued.extend(BusFrame(cob_id, self._tpdos[cob_id].length, n, _TPDO) for cob_id in due)
        if heartbeat:
            queued.append(BusFrame(self._heartbeat, _HEARTBEAT_DLC, n))
        queued += charged
        window = bus.window(n, queued)
        out_rows: list[PdoRow] = []
        out_frames: list[bytes] = []
        for frame in window.delivered:
            if frame.origin < n:
                timeline.late.append(LateFrame(n, frame.cob_id, frame.origin))
            if frame.cob_id in self._tpdos:
                if frame.origin < n:
                    self._delivered_tpdos.append(frame)
            elif frame.payload is _SDO:
                self.sdo_waiting -= 1
                self.sdo_delivered += 1
            elif isinstance(frame.payload, tuple):  # an RPDO: (its frame, its row)
                out_frames.append(frame.payload[0])
                out_rows.append(frame.payload[1])
        for frame in window.replaced:
            timeline.replaced[frame.cob_id] = timeline.replaced.get(frame.cob_id, 0) + 1
        for frame in window.backlog:
            if frame.origin == n and frame.payload is _TPDO:
                self._late_tpdos[frame.cob_id] = frame
        # The SYNC is always sent (highest priority); a backlog's SYNC is only its bus time.
        timeline.load.append(window.load)
        timeline.backlog_frames.append(len(window.backlog))
        timeline.late_frames.append(sum(1 for f in window.delivered if f.origin < n))
        timeline.waiting = tuple(f.cob_id for f in window.backlog)
        return tuple(out_rows), b"".join(out_frames)

    def _frames_of(self, due: frozenset[int], heartbeat: bool, frames: bytes) -> list[tuple[int, int]]:
        """(COB-ID, data length) of every frame of a cycle (`plan`)."""
        pairs = [(SYNC_COB_ID, _SYNC_DLC)]
        pairs += [(cob_id, self._tpdos[cob_id].length) for cob_id in due]
        pairs += [CAN_HEADER.unpack_from(frames, at) for at in range(0, len(frames), CAN_FRAME_SIZE)]
        if heartbeat:
            pairs.append((self._heartbeat, _HEARTBEAT_DLC))
        return pairs

    @property
    def waiting(self) -> bool:
        """Whether the cycle `plan` made has TPDOs to move (else `deliver` has nothing to do)."""
        return bool(self._late_tpdos or self._delivered_tpdos)

    def deliver(
        self,
        n: int,
        got: dict[int, tuple[Value, ...]],
        take_back: Callable[[int], None],
        keep: Callable[[int, tuple[Value, ...]], None],
    ) -> None:
        """After cycle `n`'s exchange: its TPDOs that wait leave `got` (and the history:
        `take_back(cob_id)`), the earlier ones the bus delivers this cycle join it (`keep`)."""
        for cob_id, frame in self._late_tpdos.items():
            values = got.pop(cob_id, None)
            if values is None:
                frame.payload = None  # the node did not send it after all: only its bus time
                continue
            take_back(cob_id)
            frame.payload = values
        for frame in self._delivered_tpdos:
            if isinstance(frame.payload, tuple):
                keep(frame.cob_id, frame.payload)


def heartbeat_cycles(heartbeat_ms: int, period_us: int) -> int:
    """The node's heartbeat producer time in cycles of `period_us` (0: it sends none)."""
    return 0 if heartbeat_ms <= 0 else max(1, round(heartbeat_ms * 1000 / period_us))


__all__ = ["SDO_ANSWER_TIMEOUT_S", "BusTimeline", "BusTiming", "LateFrame", "heartbeat_cycles"]
