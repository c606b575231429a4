"""The field recorder in the table: [recorder] validation, its generated objects (header, EDS,
value vectors) and the recording's byte layout (boardproto.recording)."""

from __future__ import annotations

import configparser
import csv
import io
import shutil
import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest
from canopen.objectdictionary import ODArray, ODRecord, ODVariable, datatypes, import_od

from boardproto import BoardTable, TableError, load_table
from boardproto.recording import (
    FIXED_HEADER_BYTES,
    HEADER_FIELDS,
    Recording,
    RecordingError,
    decode_recording,
    encode_recording,
    header_bytes,
    recording_bytes,
)
from boardproto.standard import standard_document
from boardproto.table import RECORDER_ENUMS, RecorderObject, RecorderStatusSub, RecorderTriggerSub
from boardproto.vectors import generate_value_vectors

TableWriter = Callable[[str], Path]

RECORDER = """
[recorder]
index = 0x3200
channels = 8
buffer_values = 16384
"""


def _enum(name: str, values: tuple[str, ...]) -> str:
    text = f'\n[[enum]]\nname = "{name}"\ndescription = "d"\n'
    for number, value in enumerate(values):
        text += f'\n[[enum.values]]\nname = "{value}"\nvalue = {number}\ndescription = "d"\n'
    return text


RECORDER_ENUM_TEXT = "".join(_enum(name, values) for name, values in RECORDER_ENUMS.items())


def _with_recorder(minimal_table: str, recorder: str = RECORDER, enums: str = RECORDER_ENUM_TEXT) -> str:
    # Top-level keys go before the first [[...]] of the minimal table's PDO section.
    head, pdo = minimal_table.split("[pdo]", 1)
    return f"{head}{recorder}{enums}\n[pdo]{pdo}"


def refused(path: Path, *fragments: str) -> str:
    with pytest.raises(TableError) as caught:
        load_table(path)
    message = str(caught.value)
    assert message.startswith(f"{path}: recorder: "), message
    for fragment in fragments:
        assert fragment in message, f"expected {fragment!r} in {message!r}"
    assert "\n" not in message
    return message


# --- the table ---------------------------------------------------------------------------------


def test_board_table_declares_the_recorder(table: BoardTable) -> None:
    recorder = table.recorder
    assert recorder is not None
    assert recorder.max_channels >= 8
    assert recorder.index_of(RecorderObject.STATE) == recorder.index
    assert recorder.index_of(RecorderObject.DATA) == recorder.index + 6
    # Its block follows the HIL I/O's, apart from every field and HIL object.
    assert all(entry.index not in recorder.indices for entry in table.entries)
    assert recorder.default_samples * recorder.max_channels <= recorder.buffer_values
    for name, values in RECORDER_ENUMS.items():
        assert {v.name for v in table.enum(name).values} >= set(values)


def test_a_table_without_recorder_gets_the_standard_one(minimal_table: str, write_table: TableWriter) -> None:
    table = load_table(write_table(minimal_table))
    standard = standard_document()
    recorder = table.recorder
    assert recorder is not None
    assert (recorder.index, recorder.max_channels, recorder.buffer_values) == (
        standard["recorder"]["index"],
        standard["recorder"]["channels"],
        standard["recorder"]["buffer_values"],
    )
    for name, values in RECORDER_ENUMS.items():
        assert tuple(v.name for v in table.enum(name).values) == values


def test_minimal_recorder_is_valid(minimal_table: str, write_table: TableWriter) -> None:
    recorder = load_table(write_table(_with_recorder(minimal_table))).recorder
    assert recorder is not None
    assert (recorder.index, recorder.max_channels, recorder.buffer_values) == (0x3200, 8, 16384)
    assert recorder.default_samples == 2048


def test_refuses_unknown_recorder_key(minimal_table: str, write_table: TableWriter) -> None:
    text = _with_recorder(minimal_table, RECORDER.replace("channels = 8", "chanels = 8"))
    refused(write_table(text), "unknown key 'chanels'; did you mean 'channels'?")


def test_a_recorder_key_of_the_board_replaces_only_that_key(
    minimal_table: str, write_table: TableWriter
) -> None:
    text = _with_recorder(minimal_table, "\n[recorder]\nchannels = 4\n", enums="")
    recorder = load_table(write_table(text)).recorder
    assert recorder is not None
    standard = standard_document()["recorder"]
    assert (recorder.index, recorder.max_channels, recorder.buffer_values) == (
        standard["index"],
        4,
        standard["buffer_values"],
    )


def test_refuses_recorder_outside_the_manufacturer_range(
    minimal_table: str, write_table: TableWriter
) -> None:
    refused(
        write_table(_with_recorder(minimal_table, RECORDER.replace("0x3200", "0x1F00"))),
        "index 0x1F00 outside 0x2000..0x5FF9",
    )
    refused(
        write_table(_with_recorder(minimal_table, RECORDER.replace("0x3200", "0x5FFA"))),
        "index 0x5FFA outside 0x2000..0x5FF9",
    )


def test_refuses_recorder_block_over_another_object(minimal_table: str, write_table: TableWriter) -> None:
    refused(
        write_table(_with_recorder(minimal_table, RECORDER.replace("0x3200", "0x30FE"))),
        "recorder_divider at 0x3100 collides with 'motor_duty'",
        "the recorder takes 0x30FE..0x3104",
    )


def test_refuses_zero_or_too_many_channels(minimal_table: str, write_table: TableWriter) -> None:
    refused(
        write_table(_with_recorder(minimal_table, RECORDER.replace("channels = 8", "channels = 0"))),
        "channels 0 outside 1..254",
    )
    refused(
        write_table(_with_recorder(minimal_table, RECORDER.replace("channels = 8", "channels = 255"))),
        "channels 255 outside 1..254",
    )


def test_refuses_buffer_smaller_than_one_sample(minimal_table: str, write_table: TableWriter) -> None:
    refused(
        write_table(_with_recorder(minimal_table, RECORDER.replace("16384", "4"))),
        "buffer_values 4 holds not even one sample of 8 channels",
    )


def test_a_recorder_enum_of_the_board_replaces_the_standard_one(
    minimal_table: str, write_table: TableWriter
) -> None:
    enums = _enum("recorder_state", RECORDER_ENUMS["recorder_state"])
    table = load_table(write_table(_with_recorder(minimal_table, enums=enums)))
    assert [e.name for e in table.enums] == list(RECORDER_ENUMS)  # the board's first, no second one
    assert table.enum("recorder_state").description == "d"
    standard = {e["name"]: e for e in standard_document()["enum"]}
    assert table.enum("recorder_trigger").description == standard["recorder_trigger"]["description"]


def test_the_standard_recorder_over_a_board_object_says_how_to_move_it(
    minimal_table: str, write_table: TableWriter
) -> None:
    text = minimal_table.replace("index = 0x3100", "index = 0x3203")
    refused(write_table(text), "recorder_samples at 0x3203 collides with 'motor_duty'", "[recorder] index = ")


def test_refuses_recorder_enum_missing_a_value(minimal_table: str, write_table: TableWriter) -> None:
    enums = RECORDER_ENUM_TEXT.replace('name = "either"', 'name = "both"')
    refused(
        write_table(_with_recorder(minimal_table, enums=enums)),
        "[[enum]] 'recorder_edge' lacks the value either",
    )


def test_refuses_recorder_enum_value_above_unsigned8(minimal_table: str, write_table: TableWriter) -> None:
    enums = RECORDER_ENUM_TEXT.replace('name = "done"\nvalue = 3', 'name = "done"\nvalue = 300')
    refused(
        write_table(_with_recorder(minimal_table, enums=enums)),
        "[[enum]] 'recorder_state' value 'done' = 300 does not fit its UNSIGNED8 object",
    )


# --- generated outputs -------------------------------------------------------------------------


def test_eds_describes_the_recorder(generated_dir: Path, table: BoardTable) -> None:
    recorder = table.recorder
    assert recorder is not None
    od = import_od(str(generated_dir / "board.eds"), node_id=table.node.default_node_id)
    state = od[recorder.index_of(RecorderObject.STATE)]
    assert isinstance(state, ODVariable)
    assert (state.name, state.data_type, state.access_type) == ("recorder_state", datatypes.UNSIGNED8, "rw")
    assert state.default == table.enum("recorder_state").value("idle").value

    channels = od["recorder_channels"]
    assert isinstance(channels, ODArray)
    assert channels[0].default == 0
    assert [channels[n].data_type for n in range(1, recorder.max_channels + 1)] == [
        datatypes.UNSIGNED16
    ] * recorder.max_channels
    assert sorted(channels.subindices) == list(range(recorder.max_channels + 1))

    assert od["recorder_divider"].default == 1
    assert od["recorder_samples"].default == recorder.default_samples

    trigger = od["recorder_trigger"]
    assert isinstance(trigger, ODRecord)
    assert trigger[0].default == max(RecorderTriggerSub)
    assert trigger[RecorderTriggerSub.LEVEL].data_type == datatypes.REAL32
    assert (
        trigger[RecorderTriggerSub.SOURCE].default == table.enum("recorder_trigger").value("immediate").value
    )
    status = od["recorder_status"]
    assert isinstance(status, ODRecord)
    assert all(status[sub].access_type == "ro" for sub in RecorderStatusSub)

    data = od["recorder_data"]
    assert isinstance(data, ODVariable)
    assert (data.index, data.data_type, data.access_type) == (
        recorder.index_of(RecorderObject.DATA),
        datatypes.DOMAIN,
        "ro",
    )
    for index in recorder.indices:
        entry = od[index]
        members = [entry] if isinstance(entry, ODVariable) else list(entry.values())
        assert not any(m.pdo_mappable for m in members), f"0x{index:04X} is not PDO-mappable"


def test_eds_domain_is_a_var_of_type_0x000f(generated_dir: Path, table: BoardTable) -> None:
    parser = configparser.RawConfigParser()
    parser.optionxform = str  # type: ignore[assignment,method-assign]
    parser.read(generated_dir / "board.eds")
    assert table.recorder is not None
    section = parser[f"{table.recorder.index_of(RecorderObject.DATA):04X}"]
    assert (section["ObjectType"], section["DataType"], section["AccessType"]) == ("0x7", "0x000F", "ro")
    assert "DefaultValue" not in section


def test_value_vectors_list_the_recorder(table: BoardTable) -> None:
    reader = csv.DictReader(io.StringIO(generate_value_vectors(table)))
    rows = {row["name"]: row["number"] for row in reader if row["kind"] == "recorder"}
    assert table.recorder is not None
    assert rows == {
        "index": f"0x{table.recorder.index:04X}",
        "channels": str(table.recorder.max_channels),
        "buffer_values": str(table.recorder.buffer_values),
        "default_samples": str(table.recorder.default_samples),
    }


def test_header_declares_the_recorder(generated_dir: Path, table: BoardTable) -> None:
    header = (generated_dir / "include" / "board" / "fields.hpp").read_text()
    assert table.recorder is not None
    for declaration in (
        "inline constexpr RecorderInfo kRecorder = {",
        f"    .index = 0x{table.recorder.index:04X},",
        f"inline constexpr std::uint16_t kData = 0x{table.recorder.index_of(RecorderObject.DATA):04X};",
        "inline constexpr std::uint8_t kPreTriggerPercent = 6;",
        f"inline constexpr std::size_t kFixedHeaderBytes = {FIXED_HEADER_BYTES};",
        "enum class RecorderState : std::uint8_t {",
        "// Carried by: recorder_state (0x3200 sub 0).",
    ):
        assert declaration in header, declaration
    for name, offset, _ in HEADER_FIELDS:
        assert f"Offset = {offset};" in header, name


@pytest.mark.skipif(shutil.which("g++") is None, reason="needs g++")
def test_header_layout_compiles_to_the_python_layout(generated_dir: Path, tmp_path: Path) -> None:
    checks = "\n".join(
        f"static_assert(recording::header_bytes({n}) == {header_bytes(n)});" for n in range(0, 10)
    )
    source = tmp_path / "check.cpp"
    source.write_text(
        '#include "board/fields.hpp"\nusing namespace board::recorder;\n'
        f"{checks}\nstatic_assert(kData == kState + 6);\nint main() {{ return 0; }}\n"
    )
    flags = "-std=c++20 -Wall -Wextra -Wpedantic -Wshadow -Wconversion -Werror -fsyntax-only"
    result = subprocess.run(
        ["g++", *flags.split(), f"-I{generated_dir / 'include'}", str(source)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 0, result.stderr


# --- the recording's bytes ---------------------------------------------------------------------


def _recording(channels: int = 3, samples: int = 5) -> Recording:
    return Recording(
        channels=tuple(0x2100 + c for c in range(channels)),
        divider=2,
        trigger_sample=1,
        first_cycle=100,
        trigger_cycle=102,
        last_cycle=100 + 2 * (samples - 1),
        samples=tuple(tuple(float(k * 10 + c) for c in range(channels)) for k in range(samples)),
    )


def test_recording_round_trips_and_has_the_documented_size() -> None:
    for channels in (1, 2, 3, 8):
        recording = _recording(channels)
        data = encode_recording(recording)
        assert len(data) == recording_bytes(channels, 5) == header_bytes(channels) + 4 * channels * 5
        assert header_bytes(channels) % 4 == 0
        assert decode_recording(data) == recording


def test_recording_spells_the_header_little_endian() -> None:
    data = encode_recording(_recording(channels=1, samples=1))
    assert data[:8] == bytes([1, 1, 32, 0, 2, 0, 0, 0])  # version, channels, header 32, divider 2
    assert data[28:30] == bytes([0x00, 0x21])  # channel 1: 0x2100
    assert data[32:] == bytes(4)  # 0.0f


def test_recording_cycles_follow_the_divider() -> None:
    recording = _recording()
    assert recording.cycles == (100, 102, 104, 106, 108)
    assert recording.column(2) == (2.0, 12.0, 22.0, 32.0, 42.0)
    assert not recording.periods_skipped
    late = Recording(**{**recording.__dict__, "last_cycle": 109})
    assert late.periods_skipped


def test_empty_recording_is_just_a_header() -> None:
    data = encode_recording(
        Recording(
            channels=(), divider=1, trigger_sample=0, first_cycle=0, trigger_cycle=0, last_cycle=0, samples=()
        )
    )
    assert len(data) == FIXED_HEADER_BYTES
    assert decode_recording(data).sample_count == 0


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda d: d[:10], "shorter than the 28-byte header"),
        (lambda d: bytes([2]) + d[1:], "layout version 2"),
        (lambda d: d[:-1], "but 5 samples of 3 channels take"),
        (lambda d: d[:2] + bytes([40, 0]) + d[4:], "header of 40 bytes for 3 channels"),
        (lambda d: d[:12] + bytes([5, 0, 0, 0]) + d[16:], "trigger sample 5 outside 0..4"),
    ],
)
def test_decoding_refuses_what_is_no_recording(mutate: Callable[[bytes], bytes], message: str) -> None:
    with pytest.raises(RecordingError, match=message):
        decode_recording(mutate(encode_recording(_recording())))
