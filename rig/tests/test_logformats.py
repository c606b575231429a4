"""`hilrig.session.logformats`: every format the rig writes reads back with the same frames at
the same times, through every pair of formats, in a time zone that is not UTC; the BLF header is
Vector's local time; the MF4 decodes with the generated DBC."""

from __future__ import annotations

import datetime
import itertools
import struct
import time
from collections.abc import Iterator
from pathlib import Path

import can
import pytest

from boardproto.cia301 import FunctionCode, cob_id
from hilrig.resources import DEFAULT_DBC
from hilrig.session.buslog import read_log, whole_file_logger
from hilrig.session.logformats import open_reader, open_writer

FORMATS = (".log", ".asc", ".blf", ".mf4")
EXACT_S = 1e-6
"""Every one of the four keeps microseconds (.log and .asc print them; .blf has nanoseconds and
.mf4 float seconds, both past what a float of seconds since the epoch holds)."""
ZONE = "Asia/Shanghai"
"""UTC+8 all year (no daylight saving): the offset of python-can issue #1992."""
START = 1_700_000_000.123_456  # 2023-11-14 22:13:20.123456 UTC


@pytest.fixture
def local_zone(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """This process in a time zone 8 hours from UTC, so a local/UTC mix-up shows."""
    monkeypatch.setenv("TZ", ZONE)
    time.tzset()
    yield
    monkeypatch.undo()
    time.tzset()


def frames() -> list[can.Message]:
    """Standard and extended ids, a remote frame, no data and full data, uneven gaps (a time
    a millisecond grid would round)."""
    out = []
    for k in range(12):
        out.append(
            can.Message(
                timestamp=START + k * 0.000_731 + (k % 3) * 0.123_457,
                arbitration_id=0x18FF_0010 + k if k % 4 == 3 else cob_id(FunctionCode.TPDO1, 1) + k,
                is_extended_id=k % 4 == 3,
                is_remote_frame=k == 5,
                dlc=0 if k == 5 else k % 9,  # a remote frame: python-can writes candump "#R" without its DLC
                data=b"" if k == 5 else bytes(range(k, k + k % 9)),
                channel="vcan0",
            )
        )
    return sorted(out, key=lambda m: m.timestamp)


def write(path: Path, messages: list[can.Message]) -> None:
    with whole_file_logger(path) as logger:
        for message in messages:
            logger(message)


def read(path: Path) -> list[can.Message]:
    with read_log(path) as logged:
        return list(logged)


def assert_same(got: list[can.Message], want: list[can.Message]) -> None:
    assert len(got) == len(want)
    for a, b in zip(got, want, strict=True):
        assert (a.arbitration_id, a.is_extended_id, a.is_remote_frame, a.dlc) == (
            b.arbitration_id,
            b.is_extended_id,
            b.is_remote_frame,
            b.dlc,
        )
        if not b.is_remote_frame:
            assert bytes(a.data) == bytes(b.data)
        assert a.timestamp == pytest.approx(b.timestamp, abs=EXACT_S), (a, b)


@pytest.mark.parametrize(("first", "second"), list(itertools.product(FORMATS, FORMATS)))
def test_every_pair_of_formats_keeps_frames_and_times(
    tmp_path: Path, local_zone: None, first: str, second: str
) -> None:
    want = frames()
    write(tmp_path / f"a{first}", want)
    write(tmp_path / f"b{second}", read(tmp_path / f"a{first}"))
    assert_same(read(tmp_path / f"b{second}"), want)


def _blf_start_systemtime(path: Path) -> tuple[int, ...]:
    """The header's start SYSTEMTIME: year, month, weekday, day, hour, minute, second, ms."""
    return struct.unpack_from("<8H", path.read_bytes(), 40)  # after signature, sizes and counts


def test_blf_header_is_local_time_as_vector_writes_it(tmp_path: Path, local_zone: None) -> None:
    path = tmp_path / "bus.blf"
    write(path, frames())
    year, month, _, day, hour, minute, second, ms = _blf_start_systemtime(path)
    wall = datetime.datetime.fromtimestamp(START)  # local time: 2023-11-15 06:13:20.123
    assert (year, month, day, hour, minute, second, ms) == (2023, 11, 15, 6, 13, 20, 123)
    assert (wall.day, wall.hour) == (day, hour)
    # python-can's own reader takes that header as UTC: the trap, 8 hours off
    plain = list(can.BLFReader(str(path)))
    assert plain[0].timestamp - frames()[0].timestamp == pytest.approx(8 * 3600, abs=EXACT_S)
    assert_same(read(path), frames())


def test_blf_in_utc_reads_python_cans_own_files(tmp_path: Path, local_zone: None) -> None:
    path = tmp_path / "python-can.blf"
    with can.BLFWriter(str(path)) as writer:
        for message in frames():
            writer(message)
    assert _blf_start_systemtime(path)[4] == 22  # UTC hour
    reader = open_reader(path, blf_clock="utc")
    try:
        assert_same(list(reader), frames())
    finally:
        reader.stop()
    writer = open_writer(tmp_path / "again.blf", blf_clock="utc")
    for message in frames():
        writer(message)
    writer.stop()
    assert_same(list(can.BLFReader(str(tmp_path / "again.blf"))), frames())


def test_asc_trigger_block_is_local_time_on_the_millisecond(tmp_path: Path, local_zone: None) -> None:
    path = tmp_path / "bus.asc"
    write(path, frames())
    text = path.read_text()
    assert "Begin Triggerblock Wed Nov 15 06:13:20.123 2023" in text
    first_line = next(line for line in text.splitlines() if "Rx" in line or "Tx" in line)
    assert first_line.split()[0] == "0.000456"  # the first frame 456 us after the block's start


def test_mf4_starts_at_the_first_frame_and_decodes_with_the_generated_dbc(
    tmp_path: Path, local_zone: None
) -> None:
    import cantools
    from asammdf import MDF

    database = cantools.database.load_file(DEFAULT_DBC)
    message = database.get_message_by_name("TPDO2")
    speeds = [1.5, -2.25, 1000.0]
    sent = [
        can.Message(
            timestamp=START + k * 0.001,
            arbitration_id=message.frame_id,
            is_extended_id=False,
            data=message.encode({"motor_velocity": v, "output_velocity": v / 10}),
            channel="vcan0",
        )
        for k, v in enumerate(speeds)
    ]
    path = tmp_path / "bus.mf4"
    write(path, sent)
    mdf = MDF(str(path))
    assert mdf.header.start_time.timestamp() == pytest.approx(START, abs=EXACT_S)
    decoded = mdf.extract_bus_logging({"CAN": [(str(DEFAULT_DBC), 0)]})
    signal = decoded.get("motor_velocity")
    assert list(signal.samples) == speeds
    assert list(signal.timestamps) == pytest.approx([0.0, 0.001, 0.002], abs=EXACT_S)
    # and cantools on the frames python-can reads back
    back = [database.decode_message(m.arbitration_id, bytes(m.data)) for m in read(path)]
    assert [v["motor_velocity"] for v in back] == speeds


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    from hilrig.cli import main

    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_convert_writes_the_other_format_and_says_so(
    tmp_path: Path, local_zone: None, capsys: pytest.CaptureFixture[str]
) -> None:
    write(tmp_path / "bus.log", frames())
    code, _, err = run(capsys, "convert", str(tmp_path / "bus.log"), str(tmp_path / "bus.blf"))
    assert code == 0, err
    assert f"convert: 12 frames {tmp_path / 'bus.log'} -> {tmp_path / 'bus.blf'} (Vector BLF)" in err
    assert_same(read(tmp_path / "bus.blf"), frames())
    code, _, err = run(
        capsys, "convert", str(tmp_path / "bus.blf"), str(tmp_path / "utc.blf"), "--to-blf-clock", "utc"
    )
    assert code == 0, err
    assert_same(list(can.BLFReader(str(tmp_path / "utc.blf"))), frames())


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["convert", "{tmp}/bus.log", "{tmp}/bus.txt"], "bus.txt does not end in .log, .asc, .blf, .mf4"),
        (["convert", "{tmp}/gone.log", "{tmp}/bus.asc"], "gone.log does not exist"),
        (["convert", "{tmp}/bus.log", "{tmp}/bus.log"], "is both IN and OUT"),
        (["convert", "{tmp}/empty.log", "{tmp}/bus.asc"], "empty.log holds no frames"),
        (["convert", "{tmp}/bus.log", "{tmp}/x.blf", "--from-blf-clock", "cet"], "invalid choice: 'cet'"),
    ],
)
def test_convert_refuses_bad_input_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], said: str
) -> None:
    write(tmp_path / "bus.log", frames())
    (tmp_path / "empty.log").write_text("")
    with pytest.raises(SystemExit) as exit_info:
        code, _, err = run(capsys, *[a.format(tmp=tmp_path) for a in argv])
        raise SystemExit(code)
    err = capsys.readouterr().err or err
    assert exit_info.value.code == 2
    assert said in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "bus.asc").exists()
