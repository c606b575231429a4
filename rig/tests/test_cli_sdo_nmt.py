"""`hilrig sdo read/write` (any object by index) and `hilrig nmt`, against the in-process
FakeJointNode on python-can's virtual bus, and their argument parsing without a bus."""

from __future__ import annotations

import argparse
import struct
from pathlib import Path

import can
import pytest

from boardproto.cia301 import NMT_COB_ID, NmtCommand, NmtState, SdoAbortCode
from hilrig import resources
from hilrig.cli import main
from hilrig.cli.common import UsageError
from hilrig.cli.sdo_raw import VALUE_TYPES, object_address
from hilrig.session.fake_node import FakeJointNode
from hilrig.table import RigTable

TABLE = RigTable.load()
NODE = TABLE.board.node
KP = TABLE.field("velocity_kp")
IDENTITY, DEVICE_NAME, HEARTBEAT_TIME = "0x1018", "0x1008", "0x1017"  # CiA 301 communication objects


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def on_bus(channel: str) -> list[str]:
    return ["--interface", "virtual", "--channel", channel, "--sdo-timeout", "2"]


# --- arguments ----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("0x1018:1", (0x1018, 1)),
        ("1018:1", (0x1018, 1)),
        ("6041", (0x6041, 0)),
        ("0x1400:0x0A", (0x1400, 10)),
    ],
)
def test_an_object_is_a_hex_index_and_a_sub_index(text: str, expected: tuple[int, int]) -> None:
    assert object_address(text) == expected


@pytest.mark.parametrize("text", ["0x10000", "xyz", "0x1018:256", "0x1018:a", "-1", ""])
def test_a_bad_object_address_is_refused(text: str) -> None:
    with pytest.raises(argparse.ArgumentTypeError, match=r"expected INDEX\[:SUB\]"):
        object_address(text)


@pytest.mark.parametrize(
    ("name", "text", "data", "shown"),
    [
        ("u8", "200", b"\xc8", "200 (0xC8, u8)"),
        ("u16", "0x0237", b"\x37\x02", "567 (0x0237, u16)"),
        ("i16", "-1", b"\xff\xff", "-1 (0xFFFF, i16)"),
        ("u32", "305419896", struct.pack("<I", 305419896), "305419896 (0x12345678, u32)"),
        ("i64", "-2", struct.pack("<q", -2), "-2 (0xFFFFFFFFFFFFFFFE, i64)"),
        ("f32", "0.2", struct.pack("<f", 0.2), "0.2 (0x3E4CCCCD, f32)"),
        ("f64", "1e-3", struct.pack("<d", 1e-3), "0.001 (0x3F50624DD2F1A9FC, f64)"),
        ("str", "joint", b"joint", "'joint' (6A 6F 69 6E 74, str)"),
        ("bytes", "01 02 0a", b"\x01\x02\x0a", "01 02 0A (3 bytes)"),
    ],
)
def test_values_travel_little_endian_and_print_with_their_hex(
    name: str, text: str, data: bytes, shown: str
) -> None:
    kind = VALUE_TYPES[name]
    assert kind.encode(text, "x") == data
    assert kind.describe(data) == shown


@pytest.mark.parametrize(
    ("name", "text", "message"),
    [
        ("u8", "256", "as u8: expected a whole number 0..255"),
        ("i8", "-129", "as i8: expected a whole number -128..127"),
        ("u16", "1.5", "as u16: expected a whole number"),
        ("f32", "1e39", "as f32: expected a number that fits"),
        ("bytes", "0g", "as bytes: expected hex"),
    ],
)
def test_a_value_that_does_not_fit_its_type_is_a_usage_error(name: str, text: str, message: str) -> None:
    with pytest.raises(UsageError, match=message):
        VALUE_TYPES[name].encode(text, "0x2000:00")


# --- sdo read / write against the fake node -----------------------------------------------------
def test_read_prints_value_and_hex_with_the_eds_type(
    capsys: pytest.CaptureFixture[str], fake: FakeJointNode, channel: str
) -> None:
    code, out, err = run(capsys, "sdo", "read", f"{IDENTITY}:1", *on_bus(channel))
    assert (code, err) == (0, "")
    assert out == f"0x1018:01 Identity object.Vendor-ID = {NODE.vendor_id} (0x{NODE.vendor_id:08X}, u32)\n"
    code, out, _ = run(capsys, "sdo", "read", DEVICE_NAME, *on_bus(channel))
    assert code == 0
    assert out.startswith(f"0x1008:00 Manufacturer device name = {NODE.device_name!r} (")


def test_read_of_a_table_field_is_its_f32_and_type_overrides(
    capsys: pytest.CaptureFixture[str], fake: FakeJointNode, channel: str
) -> None:
    raw = struct.pack("<f", KP.default)
    code, out, _ = run(capsys, "sdo", "read", f"{KP.index:04X}", *on_bus(channel))
    assert code == 0
    assert (
        out
        == f"0x{KP.index:04X}:00 velocity_kp = {KP.default:g} (0x{int.from_bytes(raw, 'little'):08X}, f32)\n"
    )
    code, out, _ = run(capsys, "sdo", "read", f"0x{KP.index:04X}", "--type", "u32", *on_bus(channel))
    assert code == 0
    assert (
        out.split(" = ")[1]
        == f"{int.from_bytes(raw, 'little')} (0x{int.from_bytes(raw, 'little'):08X}, u32)\n"
    )


def test_write_then_read_back(capsys: pytest.CaptureFixture[str], fake: FakeJointNode, channel: str) -> None:
    code, out, err = run(capsys, "sdo", "write", HEARTBEAT_TIME, "250", *on_bus(channel))
    assert (code, err) == (0, "")
    assert out == "0x1017:00 Producer heartbeat time := 250 (0x00FA, u16)\n"
    code, out, _ = run(capsys, "sdo", "write", HEARTBEAT_TIME, "--type", "bytes", "c8 00", *on_bus(channel))
    assert (code, out) == (0, "0x1017:00 Producer heartbeat time := C8 00 (2 bytes)\n")
    code, out, _ = run(capsys, "sdo", "read", HEARTBEAT_TIME, *on_bus(channel))
    assert (code, out) == (0, "0x1017:00 Producer heartbeat time = 200 (0x00C8, u16)\n")


def test_an_abort_is_one_line_in_words_exit_code_1(
    capsys: pytest.CaptureFixture[str], fake: FakeJointNode, channel: str
) -> None:
    code, out, err = run(capsys, "sdo", "write", f"0x{KP.index:04X}", f"{KP.max * 2:g}", *on_bus(channel))
    assert (code, out) == (1, "")
    assert err == (
        f"hilrig sdo write: error: node 0x{NODE.default_node_id:02X} refused write 0x{KP.index:04X}:00 "
        f"velocity_kp: 0x{SdoAbortCode.VALUE_TOO_HIGH:08X} value too high (max {KP.max})\n"
    )
    code, out, err = run(capsys, "sdo", "read", "0x6FFF", *on_bus(channel))
    assert (code, out) == (1, "")
    no_object = f"0x{SdoAbortCode.OBJECT_DOES_NOT_EXIST:08X} no such object in the node's dictionary"
    assert err.endswith(f"read 0x6FFF:00: {no_object}\n")
    assert err.count("\n") == 1


def test_a_silent_node_is_one_line_exit_code_1(capsys: pytest.CaptureFixture[str], channel: str) -> None:
    code, _, err = run(
        capsys, "sdo", "read", f"{IDENTITY}:1", "-i", "virtual", "-c", channel, "--sdo-timeout", "0.2"
    )
    assert code == 1
    assert err.count("\n") == 1
    assert "read 0x1018:01 Identity object.Vendor-ID: node 0x10 did not answer" in err
    assert "`hilrig scan` lists the nodes that answer" in err


def test_an_unknown_type_needs_type(capsys: pytest.CaptureFixture[str], channel: str) -> None:
    code, _, err = run(capsys, "sdo", "write", "0x6FFF", "15", *on_bus(channel))
    assert code == 2
    assert "0x6FFF:00: its type is unknown" in err and "give --type (u8, u16" in err


def test_without_an_eds_a_read_guesses_by_length_and_a_write_needs_type(
    capsys: pytest.CaptureFixture[str],
    fake: FakeJointNode,
    channel: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(resources, "DEFAULT_EDS", tmp_path / "board.eds")  # not built
    code, out, _ = run(capsys, "sdo", "read", f"{IDENTITY}:1", *on_bus(channel))
    assert (code, out) == (0, f"0x1018:01 = {NODE.vendor_id} (0x{NODE.vendor_id:08X}, u32 by its length)\n")
    code, _, err = run(capsys, "sdo", "write", HEARTBEAT_TIME, "100", *on_bus(channel))
    assert code == 2
    assert "run `make build`, or give --eds FILE" in err and "give --type" in err


# --- nmt -----------------------------------------------------------------------------------------
def test_nmt_start_waits_for_the_heartbeat_to_say_operational(
    capsys: pytest.CaptureFixture[str], fake: FakeJointNode, channel: str
) -> None:
    code, out, err = run(capsys, "nmt", "start", "--wait", *on_bus(channel)[:4])
    assert (code, err) == (0, "")
    assert out.startswith("node 0x10: operational, ") and out.endswith(" s after NMT start\n")
    assert fake.state is NmtState.OPERATIONAL
    code, out, _ = run(capsys, "nmt", "stop", "0x10", "-w", *on_bus(channel)[:4])
    assert code == 0 and out.startswith("node 0x10: stopped, ")
    assert fake.state is NmtState.STOPPED


def test_nmt_reset_waits_for_the_boot_up(
    capsys: pytest.CaptureFixture[str], fake: FakeJointNode, channel: str
) -> None:
    code, out, err = run(capsys, "nmt", "reset-comm", "16", "--wait", *on_bus(channel)[:4])
    assert (code, err) == (0, "")
    assert out.startswith("node 0x10: boot-up ") and out.endswith(
        "after NMT reset-comm, now pre_operational\n"
    )


def test_nmt_all_addresses_node_0(capsys: pytest.CaptureFixture[str], channel: str) -> None:
    with can.Bus(interface="virtual", channel=channel) as listener:
        code, out, _ = run(capsys, "nmt", "preop", "all", *on_bus(channel)[:4])
        frame = listener.recv(1.0)
    assert (code, out) == (0, f"NMT preop sent to all nodes on virtual channel {channel}\n")
    assert frame is not None and frame.arbitration_id == NMT_COB_ID
    assert bytes(frame.data) == bytes([NmtCommand.ENTER_PRE_OPERATIONAL, 0])


def test_nmt_wait_on_a_silent_node_is_one_line_exit_code_1(
    capsys: pytest.CaptureFixture[str], fake: FakeJointNode, channel: str
) -> None:
    code, out, err = run(capsys, "nmt", "start", "5", "--wait", "--timeout", "0.3", *on_bus(channel)[:4])
    assert (code, out) == (1, "")
    assert err.startswith(
        "hilrig nmt: error: node 0x05: no heartbeat showing operational within 0.3 s of NMT start; "
        "heard nothing from it"
    )
    assert err.count("\n") == 1


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["nmt", "start", "all", "--wait"], "--wait needs one node"),
        (["nmt", "begin"], "invalid choice: 'begin'"),
        (["nmt", "start", "200"], "expected a node id 1..127"),
        (["sdo", "read", "0x1018:1", "--type", "uint16"], "unknown type 'uint16'"),
        (["sdo", "write", "0x1017", "--type", "u16", "65536"], "0x1017:00 Producer heartbeat time as u16"),
        (["sdo", "read"], "the following arguments are required: INDEX[:SUB]"),
        (["sdo"], "argument ACTION: invalid choice: 'virtual' (choose from 'read', 'write')"),
    ],
)
def test_bad_nmt_and_sdo_command_lines_are_one_line_exit_code_2(
    capsys: pytest.CaptureFixture[str], argv: list[str], expected: str, channel: str
) -> None:
    code, out, err = run(capsys, *argv, "-i", "virtual", "-c", channel)
    assert (code, out) == (2, "")
    assert expected in err and err.count("\n") == 1, err
