"""A recorded bus log into the tracer: `hilrig replay FILE --trace OUT.rrd`.

A log from `hilrig record` (a real board on can0, or any scenario's bus.log) becomes the same
kind of Rerun trace a live run makes: every PDO field decoded with the generated DBC, grouped by
SYNC into cycles (the RPDOs before SYNC n and the TPDOs after it are cycle n, as the lockstep
rig and a SYNC-driven board see them), on the `cycle` timeline and the wall-clock timeline of
the recording; EMCY, SDO aborts and NMT state changes from heartbeats as text log entries;
and the bus measurements a live run's trace has (`hilrig.observe.busmeter`: load per 10 ms
window, each TPDO's delay after its SYNC by the log's timestamps, late, missing and malformed
TPDOs and error frames as events and counts).
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import can

from boardproto.cia301 import (
    EMCY_ERROR_RESET,
    HEARTBEAT_STATE_MASK,
    SYNC_COB_ID,
    EmcyLayout,
    NmtState,
    emcy_cob_id,
    heartbeat_cob_id,
    sdo_response_cob_id,
    split_emcy,
)
from hilrig.table import RigTable
from hilrig.wire.node import EmcyRecord
from hilrig.wire.sdo import abort_text, parse_abort

if TYPE_CHECKING:
    from hilrig.observe.sinks import TraceSink
    from hilrig.observe.tracer import Tracer
    from hilrig.session.buslog import NodeDbc

Value = float | int


@dataclass
class LogTraceStats:
    frames: int = 0
    cycles: int = 0
    decoded: int = 0
    """PDO frames decoded with the DBC."""
    undecodable: int = 0
    """Frames on a PDO's COB-ID that did not fit its DBC message (wrong length)."""
    events: int = 0
    """EMCY, SDO aborts and NMT changes logged as text."""


def trace_log(
    messages: Iterable[can.Message],
    dbc: NodeDbc,
    table: RigTable,
    node_id: int,
    tracer: Tracer,
    progress: Callable[[int], None] | None = None,
) -> LogTraceStats:
    """Send the frames of a log into `tracer` (made with clock="wall": `t` is the log's own
    timestamps); returns what was done. The caller closes the tracer."""
    from hilrig.observe.busmeter import BusMeter, PdoSpec
    from hilrig.observe.paths import EMCY_PATH
    from hilrig.observe.sinks import Severity

    stats = LogTraceStats()
    meter = BusMeter(
        {
            pdo.cob_id(node_id): PdoSpec(
                pdo.name, pdo.length_bytes, pdo in table.board.tpdos, pdo.transmission_type
            )
            for pdo in (*table.board.tpdos, *table.board.rpdos)
            if pdo.enabled and pdo.entries
        },
        bitrate=tracer.bitrate,
    )
    tpdo_ids = {pdo.cob_id(node_id) for pdo in table.board.tpdos}
    emcy_id, sdo_answer_id = emcy_cob_id(node_id), sdo_response_cob_id(node_id)
    heartbeat_id = heartbeat_cob_id(node_id)
    cycle = -1  # index of the open cycle (the last SYNC seen); -1 before the first SYNC
    cycle_t = 0.0
    sent: dict[str, Value] = {}  # RPDO values since the last SYNC: they belong to the next cycle
    open_sent: dict[str, Value] = {}
    received: dict[str, Value] = {}
    first_t: float | None = None
    heartbeat_state: NmtState | None = None

    def close_cycle() -> None:
        if cycle >= 0:
            tracer.log_cycle(cycle, cycle_t, received, open_sent, None)
            stats.cycles += 1

    for message in messages:
        stats.frames += 1
        if progress is not None and stats.frames % 10_000 == 0:
            progress(stats.frames)
            tracer.log_bus(meter.take())
        t = message.timestamp
        if message.is_error_frame:
            meter.frame(t, max(cycle, 0), message.arbitration_id, 0, error=True)
            continue
        if message.is_extended_id or message.is_remote_frame:
            continue
        first_t = t if first_t is None else first_t
        cob_id, data = message.arbitration_id, bytes(message.data)
        at_cycle = max(cycle, 0)
        if cob_id == SYNC_COB_ID:  # SYNC: the open cycle is complete, the next one starts
            close_cycle()
            cycle, cycle_t = cycle + 1, t
            open_sent, sent, received = sent, {}, {}
            meter.frame(t, cycle, cob_id, len(data))
            continue
        meter.frame(t, at_cycle, cob_id, len(data))
        if cob_id == emcy_id and len(data) == EmcyLayout.FRAME_BYTES:
            emcy = split_emcy(data)
            record = EmcyRecord(emcy.code, emcy.register, emcy.manufacturer, at_cycle, t - first_t)
            level = Severity.INFO if emcy.code == EMCY_ERROR_RESET else Severity.ERROR
            tracer.log_text(EMCY_PATH, f"{record} (s into the log)", level, t=t, cycle=at_cycle)
            stats.events += 1
            continue
        if cob_id == sdo_answer_id and (abort := parse_abort(data)) is not None:
            tracer.log_sdo_abort(abort_text(abort, table), abort.code, cycle=at_cycle, t=t)
            stats.events += 1
            continue
        if cob_id == heartbeat_id and len(data) == 1:
            try:
                state = NmtState(data[0] & HEARTBEAT_STATE_MASK)
            except ValueError:
                continue
            if state is not heartbeat_state:
                heartbeat_state = state
                tracer.log_nmt(state, t, cycle=at_cycle, source="heartbeat in the log")
                stats.events += 1
            continue
        dbc_message = dbc.message(cob_id)
        if dbc_message is None:
            continue
        try:
            values = dbc_message.decode(data, decode_choices=False, scaling=True)
        except Exception:  # a frame that does not fit its message (wrong length): not a value
            stats.undecodable += 1
            continue
        stats.decoded += 1
        fields = {name: value for name, value in values.items() if isinstance(value, int | float)}
        if cob_id in tpdo_ids:
            received.update(fields)
        else:
            sent.update(fields)
    close_cycle()
    tracer.log_bus(meter.take(final=True))
    return stats


class LiveBusTrace:
    """A can.Listener (duck-typed) that streams a live bus into a Rerun trace as it goes: the
    frames are decoded by `trace_log` (PDO fields by the DBC, grouped by SYNC, EMCY, SDO aborts,
    NMT) on a thread of its own, on the wall-clock timeline, into `sinks` (a viewer: spawn, web,
    connect). `stop()` sends what is left and closes the trace; `stats` says what went in.
    Python-can's notifier thread only queues each frame, so a slow viewer never stalls the
    recording beside it."""

    def __init__(
        self, sinks: Sequence[TraceSink], dbc: NodeDbc, table: RigTable, node_id: int, name: str
    ) -> None:
        from hilrig.observe.tracer import Tracer

        self.tracer = Tracer(list(sinks), table, clock="wall", recording_name=name)
        self.stats = LogTraceStats()
        self._frames: queue.SimpleQueue[can.Message | None] = queue.SimpleQueue()
        self._error: BaseException | None = None
        self._thread = threading.Thread(
            target=self._run, args=(dbc, table, node_id), name="hilrig-live-trace", daemon=True
        )
        self._thread.start()

    def _run(self, dbc: NodeDbc, table: RigTable, node_id: int) -> None:
        try:
            self.stats = trace_log(iter(self._frames.get, None), dbc, table, node_id, self.tracer)
        except BaseException as error:  # reported by stop(), on the caller's thread
            self._error = error

    def on_message_received(self, msg: can.Message) -> None:
        self._frames.put(msg)

    __call__ = on_message_received  # how can.Notifier calls its listeners

    def on_sent(self, cob_id: int, data: bytes) -> None:
        """A frame this process sent itself (a bus does not hand a sender its own frames), stamped
        now as python-can stamps received frames."""
        self._frames.put(
            can.Message(arbitration_id=cob_id, data=data, is_extended_id=False, timestamp=time.time())
        )

    def on_error(self, exc: Exception) -> None:  # python-can's Listener interface
        pass

    def stop(self) -> None:
        """End the stream: the frames queued so far go in, then the trace is closed."""
        if self._thread.is_alive():
            self._frames.put(None)
            self._thread.join()
        self.tracer.close()
        if self._error is not None:
            error, self._error = self._error, None
            raise RuntimeError(f"the live trace failed: {error}") from error


__all__ = ["LiveBusTrace", "LogTraceStats", "trace_log"]
