"""The board's field recorder from the host: settings over SDO, arm, wait, upload the recording
by SDO block transfer, and write it as a CSV and a Rerun trace that looks like a lockstep one.

    settings = CaptureSettings(channels=("motor_velocity", "joint_torque"), samples=2000,
                               trigger="level", trigger_field="velocity_setpoint", level=1.0,
                               pre_trigger_percent=20)
    recorder = RecorderClient(node, table)
    recorder.configure(settings)
    recorder.arm()
    recorder.wait_until_done(on_progress=print)
    recording = recorder.upload()              # boardproto.recording.Recording
    write_csv(recording, table, "capture.csv", period_s=0.001)
    write_rrd(recording, table, "capture.rrd", period_s=0.001)

What the objects mean is board.toml's [recorder]; the recording's bytes are
`boardproto.recording`. Sample k was taken at the firmware's control cycle
`recording.cycle_of(k)`. In lockstep that number counts the SYNCs the firmware process has seen
(every SYNC runs a cycle, pre-operational too), while the rig numbers its cycles from 0: when
the rig sent every SYNC since the firmware started, firmware cycle c is the rig's cycle c - 1
(whose TPDOs carry what the recorder sampled at the end of cycle c).
"""

from __future__ import annotations

import contextlib
import csv
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

from boardproto import Field
from boardproto.recording import Recording, decode_recording
from boardproto.table import Recorder, RecorderObject, RecorderStatusSub, RecorderTriggerSub
from hilrig.errors import RigError
from hilrig.files import replacing
from hilrig.table import RigTable

if TYPE_CHECKING:
    from hilrig.observe.tracer import Tracer

RECORDER_EVENTS = "/events/recorder"
"""Entity path of the capture's text events (the trigger) in its Rerun trace."""


class CaptureError(RigError):
    """The capture cannot go on: settings the table refuses, a recording that never ends..."""


class SdoObjects(Protocol):
    """What the recorder client needs of a node: hilrig.wire.node.BoardNode has these."""

    def download(self, index: int, subindex: int, data: bytes, what: str | None = None) -> None: ...
    def upload(self, index: int, subindex: int, what: str | None = None) -> bytes: ...
    def block_upload(self, index: int, subindex: int, what: str) -> bytes: ...


@dataclass(frozen=True)
class CaptureSettings:
    """A recording to make: the fields (by name), how many samples, one every `divider` cycles,
    and the trigger (names are those of board.toml's recorder_trigger and recorder_edge)."""

    channels: tuple[str, ...]
    samples: int
    divider: int = 1
    trigger: str = "immediate"
    trigger_field: str | None = None
    level: float = 0.0
    edge: str = "rising"
    mask: int = 0  # flag trigger: the bits watched
    pre_trigger_percent: int = 0


@dataclass(frozen=True)
class Progress:
    state: str  # a recorder_state name
    samples_taken: int
    samples_left: int


def recorder_of(table: RigTable) -> Recorder:
    recorder = table.board.recorder
    if recorder is None:
        raise CaptureError(f"{table.board.source} declares no [recorder]: this board has none")
    return recorder


def check_settings(settings: CaptureSettings, table: RigTable) -> list[Field]:
    """The channels' fields; CaptureError when the table says the firmware would refuse."""
    recorder = recorder_of(table)
    fields: list[Field] = []
    for name in settings.channels:
        entry = table.entry(name)  # FieldNameError with close matches
        if not isinstance(entry, Field):
            raise CaptureError(f"{name} is a HIL I/O object: the recorder records board fields")
        if entry.subindex:
            raise CaptureError(
                f"{name} is sub {entry.subindex} of the array at 0x{entry.index:04X}: the recorder names "
                "its channels by object index and records plain fields only"
            )
        fields.append(entry)
    if not fields:
        raise CaptureError("no channels: name at least one field")
    if len(fields) > recorder.max_channels:
        raise CaptureError(f"{len(fields)} channels: the recorder records {recorder.max_channels} at most")
    if len(set(settings.channels)) != len(settings.channels):
        raise CaptureError("a field is named twice")
    fit = recorder.buffer_values // len(fields)
    if not 1 <= settings.samples <= fit:
        raise CaptureError(
            f"{settings.samples} samples of {len(fields)} channels: 1..{fit} fit the recorder's "
            f"{recorder.buffer_values} values"
        )
    if not 1 <= settings.divider <= 0xFFFF:
        raise CaptureError(f"divider {settings.divider}: expected 1..65535")
    if not 0 <= settings.pre_trigger_percent <= 100:
        raise CaptureError(f"pre-trigger share {settings.pre_trigger_percent} %: expected 0..100")
    table.board.enum("recorder_trigger").value(settings.trigger)  # UnknownNameError names them
    table.board.enum("recorder_edge").value(settings.edge)
    if settings.trigger != "immediate":
        if settings.trigger_field is None:
            raise CaptureError(f"a {settings.trigger} trigger needs a trigger field")
        watched = table.entry(settings.trigger_field)
        if not isinstance(watched, Field):
            raise CaptureError(f"{settings.trigger_field} is no board field: a trigger watches a field")
        if watched.subindex:
            raise CaptureError(
                f"{settings.trigger_field} is an array's member: a trigger watches a plain field"
            )
    if settings.trigger == "flag" and settings.mask == 0:
        raise CaptureError("a flag trigger needs the bits to watch")
    return fields


class RecorderClient:
    """The recorder's objects on one node, by what they mean."""

    def __init__(self, node: SdoObjects, table: RigTable) -> None:
        self.node = node
        self.table = table
        self.recorder = recorder_of(table)
        self._states = table.board.enum("recorder_state")

    def _write(self, recorder_object: RecorderObject, sub: int, fmt: str, value: float) -> None:
        index = self.recorder.index_of(recorder_object)
        what = f"write {recorder_object.object_name} sub {sub}"
        self.node.download(index, sub, struct.pack(fmt, value), what)

    def _read(self, recorder_object: RecorderObject, sub: int, fmt: str) -> int:
        index = self.recorder.index_of(recorder_object)
        data = self.node.upload(index, sub, f"read {recorder_object.object_name} sub {sub}")
        return int(struct.unpack(fmt, data[: struct.calcsize(fmt)])[0])

    def _set_state(self, name: str) -> None:
        self._write(RecorderObject.STATE, 0, "<B", self._states.value(name).value)

    def configure(self, settings: CaptureSettings) -> None:
        """Stops any recording (settings are refused while one is under way), then writes every
        setting; the node checks each and refuses in words (SdoAbortError)."""
        fields = check_settings(settings, self.table)
        board = self.table.board
        self.disarm()
        self._write(RecorderObject.CHANNELS, 0, "<B", 0)
        for n, field in enumerate(fields, start=1):
            self._write(RecorderObject.CHANNELS, n, "<H", field.index)
        self._write(RecorderObject.CHANNELS, 0, "<B", len(fields))
        self._write(RecorderObject.DIVIDER, 0, "<H", settings.divider)
        self._write(RecorderObject.SAMPLES, 0, "<I", settings.samples)
        watched = settings.trigger_field
        trigger_index = 0 if watched is None else self.table.entry(watched).index
        for sub, fmt, value in (
            (RecorderTriggerSub.SOURCE, "<B", board.enum("recorder_trigger").value(settings.trigger).value),
            (RecorderTriggerSub.FIELD, "<H", trigger_index),
            (RecorderTriggerSub.LEVEL, "<f", settings.level),
            (RecorderTriggerSub.EDGE, "<B", board.enum("recorder_edge").value(settings.edge).value),
            (RecorderTriggerSub.MASK, "<I", settings.mask),
            (RecorderTriggerSub.PRE_TRIGGER_PERCENT, "<B", settings.pre_trigger_percent),
        ):
            self._write(RecorderObject.TRIGGER, sub, fmt, value)

    def arm(self) -> None:
        self._set_state("armed")

    def disarm(self) -> None:
        """Stop and discard: the recorder goes idle."""
        self._set_state("idle")

    def progress(self) -> Progress:
        state = self._read(RecorderObject.STATE, 0, "<B")
        return Progress(
            state=self._states.label(state),
            samples_taken=self._read(RecorderObject.STATUS, RecorderStatusSub.SAMPLES_TAKEN, "<I"),
            samples_left=self._read(RecorderObject.STATUS, RecorderStatusSub.SAMPLES_LEFT, "<I"),
        )

    def wait_until_done(
        self,
        *,
        poll_s: float = 0.1,
        timeout_s: float | None = None,
        on_progress: Callable[[Progress], None] | None = None,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        """Polls the state until done. On timeout, Ctrl-C or any error the recorder is disarmed
        (a recording left armed would go on sampling on the board), then the error goes on."""
        deadline = None if timeout_s is None else clock() + timeout_s
        try:
            while True:
                progress = self.progress()
                if on_progress is not None:
                    on_progress(progress)
                if progress.state == "done":
                    return
                if progress.state == "idle":
                    raise CaptureError(
                        "the recorder went idle before it was done (stopped by another client?)"
                    )
                if deadline is not None and clock() >= deadline:
                    raise CaptureError(
                        f"not done after {timeout_s:g} s ({progress.state}, {progress.samples_taken} samples "
                        "taken): disarmed; is the trigger right, and does the board run control cycles?"
                    )
                sleep(poll_s)
        except BaseException:
            with contextlib.suppress(RigError):
                self.disarm()
            raise

    def upload(self) -> Recording:
        """The recording, by SDO block upload of the DOMAIN."""
        index = self.recorder.index_of(RecorderObject.DATA)
        data = self.node.block_upload(index, 0, f"upload {RecorderObject.DATA.object_name}")
        recording = decode_recording(data)
        known = {f.index for f in self.table.board.fields if not f.subindex}
        unknown = ", ".join(f"0x{i:04X}" for i in recording.channels if i not in known)
        if unknown:
            raise CaptureError(f"the recording names objects this table has no field at: {unknown}")
        return recording


# --- Files --------------------------------------------------------------------------------------


def channel_fields(recording: Recording, table: RigTable) -> list[Field]:
    """The recording's channels as the table's fields."""
    by_index = {f.index: f for f in table.board.fields if not f.subindex}
    return [by_index[index] for index in recording.channels]


def column_header(field: Field) -> str:
    """'motor_velocity [rad/s]': the name and unit, as the trace's series are named."""
    return f"{field.name} [{field.unit}]"


def _float32_text(value: float) -> str:
    """The shortest text that reads back as the same REAL32 (0.1, not 0.10000000149011612)."""
    import numpy as np

    return str(np.float32(value))


def write_csv(recording: Recording, table: RigTable, path: str | Path, *, period_s: float) -> None:
    """One row per sample: cycle, time (cycle * period, as the trace's sim_time), one column per
    channel headed 'name [unit]'. Written whole or not at all (temporary file, then rename)."""
    fields = channel_fields(recording, table)
    with replacing(Path(path)) as temporary, temporary.open("w", newline="") as file:
        writer = csv.writer(file, lineterminator="\n")
        writer.writerow(["cycle", "time [s]", *(column_header(f) for f in fields)])
        for k, row in enumerate(recording.samples):
            cycle = recording.cycle_of(k)
            writer.writerow([cycle, f"{cycle * period_s:.9g}", *(_float32_text(v) for v in row)])


def log_recording(tracer: Tracer, recording: Recording, table: RigTable, *, period_s: float) -> None:
    """The recording into a tracer, sample by sample as if received in lockstep cycles: the same
    entity paths, series names and value labels as a trace of the rig, and the trigger as a text
    event on RECORDER_EVENTS."""
    names = [f.name for f in channel_fields(recording, table)]
    for k, row in enumerate(recording.samples):
        cycle = recording.cycle_of(k)
        tracer.log_cycle(cycle, cycle * period_s, dict(zip(names, row, strict=True)), {}, None)
    if recording.samples:
        cycle = recording.cycle_of(recording.trigger_sample)
        text = f"recorder trigger (sample {recording.trigger_sample} of {recording.sample_count})"
        tracer.on_event(RECORDER_EVENTS, text, warning=False, cycle=cycle, t=cycle * period_s)


def write_rrd(recording: Recording, table: RigTable, path: str | Path, *, period_s: float) -> None:
    """The recording as a Rerun .rrd (timelines `cycle` and `sim_time`), written whole or not at
    all."""
    from hilrig.observe.sinks import TraceSink
    from hilrig.observe.tracer import Tracer

    target = Path(path)
    with replacing(target) as temporary:
        tracer = Tracer(TraceSink.rrd(temporary), table, background=False, recording_name=target.stem)
        try:
            log_recording(tracer, recording, table, period_s=period_s)
        finally:
            tracer.close()
