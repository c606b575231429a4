"""`hilrig capture` without a bus: the settings the table allows, what the client writes to the
recorder's objects, waiting (and disarming on a timeout or Ctrl-C), decoding the upload, and the
CSV and Rerun files."""

from __future__ import annotations

import csv
import struct
from pathlib import Path

import pytest

from boardproto.recording import Recording, encode_recording
from boardproto.table import BitSet, RecorderObject, RecorderStatusSub, RecorderTriggerSub
from hilrig.apps.capture import (
    RECORDER_EVENTS,
    CaptureError,
    CaptureSettings,
    Progress,
    RecorderClient,
    check_settings,
    column_header,
    write_csv,
    write_rrd,
)
from hilrig.cli import main
from hilrig.observe.paths import entity_paths
from hilrig.table import FaultFlags, RigTable

TABLE = RigTable.load()
RECORDER = TABLE.board.recorder
assert RECORDER is not None
STATE = TABLE.board.enum("recorder_state")
# A field whose values are a [[bitset]]: what a flag trigger watches.
BITSET_FIELD = next(name for name, values in TABLE.board.named_values.items() if isinstance(values, BitSet))


class FakeRecorderNode:
    """The recorder's objects as a node would hold them: writes are kept, reads answer from
    `values`, the block upload returns `recording`."""

    def __init__(self) -> None:
        self.writes: list[tuple[int, int, bytes]] = []
        self.values: dict[tuple[int, int], bytes] = {}
        self.recording = b""
        self.states: list[str] = []  # what successive state reads return

    def download(self, index: int, subindex: int, data: bytes, what: str | None = None) -> None:
        self.writes.append((index, subindex, data))

    def upload(self, index: int, subindex: int, what: str | None = None) -> bytes:
        if (index, subindex) == (RECORDER.index_of(RecorderObject.STATE), 0) and self.states:
            return bytes([STATE.value(self.states.pop(0)).value])
        return self.values.get((index, subindex), bytes(4))

    def block_upload(self, index: int, subindex: int, what: str) -> bytes:
        assert (index, subindex) == (RECORDER.index_of(RecorderObject.DATA), 0)
        return self.recording

    def written(self, recorder_object: RecorderObject, sub: int = 0) -> list[bytes]:
        index = RECORDER.index_of(recorder_object)
        return [data for i, s, data in self.writes if (i, s) == (index, sub)]


def _recording(samples: int = 4) -> Recording:
    velocity, flags = TABLE.board.field("motor_velocity"), TABLE.board.field("fault_flags")
    return Recording(
        channels=(velocity.index, flags.index),
        divider=2,
        trigger_sample=1,
        first_cycle=100,
        trigger_cycle=102,
        last_cycle=100 + 2 * (samples - 1),
        samples=tuple((0.1 * k, float(FaultFlags.COMMAND_WATCHDOG if k else 0)) for k in range(samples)),
    )


# --- Settings ------------------------------------------------------------------------------------


def test_settings_the_table_refuses() -> None:
    too_many = tuple(f.name for f in TABLE.board.fields[: RECORDER.max_channels + 1])
    refusals = {
        "at most": CaptureSettings(channels=too_many, samples=1),
        "HIL I/O object": CaptureSettings(channels=("motor_duty",), samples=1),
        "fit the recorder": CaptureSettings(channels=("motor_velocity",), samples=RECORDER.buffer_values + 1),
        "needs a trigger field": CaptureSettings(channels=("motor_velocity",), samples=10, trigger="level"),
        "needs the bits": CaptureSettings(
            channels=("motor_velocity",), samples=10, trigger="flag", trigger_field=BITSET_FIELD
        ),
        "named twice": CaptureSettings(channels=("motor_velocity", "motor_velocity"), samples=10),
    }
    for fragment, settings in refusals.items():
        with pytest.raises(CaptureError, match=fragment):
            check_settings(settings, TABLE)
    with pytest.raises(KeyError, match="did you mean 'level'"):
        check_settings(CaptureSettings(channels=("motor_velocity",), samples=1, trigger="levle"), TABLE)


def test_configure_stops_then_writes_every_setting_in_order() -> None:
    node = FakeRecorderNode()
    settings = CaptureSettings(
        channels=("motor_velocity", "joint_torque"),
        samples=2000,
        divider=3,
        trigger="level",
        trigger_field="velocity_setpoint",
        level=1.5,
        edge="falling",
        pre_trigger_percent=20,
    )
    RecorderClient(node, TABLE).configure(settings)
    state_index = RECORDER.index_of(RecorderObject.STATE)
    assert node.writes[0] == (state_index, 0, bytes([STATE.value("idle").value])), "idle first"
    assert node.written(RecorderObject.CHANNELS, 0) == [b"\x00", b"\x02"], "count 0, entries, count"
    assert node.written(RecorderObject.CHANNELS, 1) == [
        struct.pack("<H", TABLE.entry("motor_velocity").index)
    ]
    assert node.written(RecorderObject.CHANNELS, 2) == [struct.pack("<H", TABLE.entry("joint_torque").index)]
    assert node.written(RecorderObject.DIVIDER) == [struct.pack("<H", 3)]
    assert node.written(RecorderObject.SAMPLES) == [struct.pack("<I", 2000)]
    trigger = {sub: node.written(RecorderObject.TRIGGER, sub) for sub in RecorderTriggerSub}
    assert trigger[RecorderTriggerSub.SOURCE] == [
        bytes([TABLE.board.enum("recorder_trigger").value("level").value])
    ]
    assert trigger[RecorderTriggerSub.FIELD] == [struct.pack("<H", TABLE.entry("velocity_setpoint").index)]
    assert trigger[RecorderTriggerSub.LEVEL] == [struct.pack("<f", 1.5)]
    assert trigger[RecorderTriggerSub.EDGE] == [
        bytes([TABLE.board.enum("recorder_edge").value("falling").value])
    ]
    assert trigger[RecorderTriggerSub.PRE_TRIGGER_PERCENT] == [bytes([20])]
    assert not any(i == state_index for i, _, _ in node.writes[1:]), "configure does not arm"


# --- Waiting -------------------------------------------------------------------------------------


def test_wait_reports_progress_until_done() -> None:
    node = FakeRecorderNode()
    node.states = ["armed", "armed", "triggered", "done"]
    status = RECORDER.index_of(RecorderObject.STATUS)
    node.values[(status, RecorderStatusSub.SAMPLES_TAKEN)] = struct.pack("<I", 42)
    seen: list[Progress] = []
    RecorderClient(node, TABLE).wait_until_done(on_progress=seen.append, sleep=lambda s: None)
    assert [p.state for p in seen] == ["armed", "armed", "triggered", "done"]
    assert seen[0].samples_taken == 42
    assert node.writes == [], "done: nothing disarmed"


def test_wait_disarms_on_timeout_and_on_ctrl_c() -> None:
    idle = (RECORDER.index_of(RecorderObject.STATE), 0, bytes([STATE.value("idle").value]))
    node = FakeRecorderNode()
    node.states = ["armed"] * 10
    now = iter(float(t) for t in range(100))
    with pytest.raises(CaptureError, match="not done after 3 s"):
        RecorderClient(node, TABLE).wait_until_done(
            timeout_s=3, clock=lambda: next(now), sleep=lambda s: None
        )
    assert node.writes == [idle]

    node = FakeRecorderNode()
    node.states = ["armed"] * 10

    def interrupt(seconds: float) -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        RecorderClient(node, TABLE).wait_until_done(sleep=interrupt)
    assert node.writes == [idle]


def test_upload_decodes_the_recording() -> None:
    node = FakeRecorderNode()
    node.recording = encode_recording(_recording())
    recording = RecorderClient(node, TABLE).upload()
    assert recording.cycles == (100, 102, 104, 106)
    assert recording.column(0)[1] == pytest.approx(0.1)
    node.recording = encode_recording(Recording(**{**_recording().__dict__, "channels": (0x3100, 0x2100)}))
    with pytest.raises(CaptureError, match="no field at: 0x3100"):
        RecorderClient(node, TABLE).upload()


# --- Files ---------------------------------------------------------------------------------------


def test_csv_has_cycle_time_and_a_column_per_field_with_its_unit(tmp_path: Path) -> None:
    path = tmp_path / "out" / "capture.csv"
    write_csv(_recording(), TABLE, path, period_s=0.001)
    with path.open() as file:
        rows = list(csv.reader(file))
    assert rows[0] == ["cycle", "time [s]", "motor_velocity [rad/s]", "fault_flags [1]"]
    assert rows[1] == ["100", "0.1", "0.0", "0.0"]
    assert rows[2] == ["102", "0.102", "0.1", "16.0"], "REAL32 values in their shortest spelling"
    assert len(rows) == 5
    assert [p.name for p in path.parent.iterdir()] == ["capture.csv"], "no temporary file left"


def test_csv_is_replaced_whole_or_not_at_all(tmp_path: Path) -> None:
    path = tmp_path / "capture.csv"
    path.write_text("the last capture\n")
    broken = Recording(**{**_recording().__dict__, "channels": (0x2100, 0x3100)})
    with pytest.raises(KeyError):
        write_csv(broken, TABLE, path, period_s=0.001)
    assert path.read_text() == "the last capture\n"
    assert [p.name for p in tmp_path.iterdir()] == ["capture.csv"]


def test_column_header_is_the_trace_series_name() -> None:
    assert column_header(TABLE.board.field("joint_torque")) == "joint_torque [N*m]"


def test_rrd_looks_like_a_lockstep_trace(tmp_path: Path) -> None:
    pytest.importorskip("rerun")
    from hilrig.observe.reader import Trace

    path = tmp_path / "capture.rrd"
    write_rrd(_recording(), TABLE, path, period_s=0.001)
    trace = Trace.read(path)
    paths = entity_paths(TABLE)
    velocity = paths["motor_velocity"]
    assert velocity == "/fields/virtual_sensors/motor_velocity"
    assert trace.cycles[velocity] == [100, 102, 104, 106]
    assert trace.times[velocity] == pytest.approx([0.1, 0.102, 0.104, 0.106])
    assert trace.scalars[velocity] == pytest.approx([0.0, 0.1, 0.2, 0.3], abs=1e-6)
    assert trace.series_names[velocity] == "motor_velocity [rad/s]"
    assert trace.scalars[paths["fault_flags"]] == [0.0, 16.0, 16.0, 16.0]
    (event,) = trace.texts[RECORDER_EVENTS]
    assert "trigger" in event[0]


# --- Command line --------------------------------------------------------------------------------


def test_command_line_mistakes_are_usage_errors(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["capture", "motor_velocty"]) == 2
    assert "did you mean 'motor_velocity'" in capsys.readouterr().err
    flag_trigger = ["--trigger", "flag", "--trigger-field", BITSET_FIELD]
    assert main(["capture", "motor_velocity", *flag_trigger, "--bits", "comand_watchdog"]) == 2
    assert "did you mean 'command_watchdog'" in capsys.readouterr().err
    assert main(["capture", "motor_velocity", "--samples", str(RECORDER.buffer_values + 1)]) == 2
    assert "fit the recorder" in capsys.readouterr().err
    assert main(["capture", "motor_velocity", "--pre", "101"]) == 2
    assert "0..100" in capsys.readouterr().err
