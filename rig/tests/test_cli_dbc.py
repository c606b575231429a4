"""`hilrig dbc`: the DBC for any node id, to stdout or a file, with the table's named values;
a bad node id is one line and exit code 2. No bus needed."""

from __future__ import annotations

import io
import subprocess
import sys
from pathlib import Path

import cantools
import cantools.logreader
import pytest
from cantools.database.can import Database

from boardproto.cia301 import FunctionCode, cob_id
from hilrig.cli import main
from hilrig.table import RigTable

TABLE = RigTable.load().board
HILRIG = [sys.executable, "-m", "hilrig.cli"]


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def load(text: str) -> Database:
    database = cantools.database.load_string(text, "dbc")
    assert isinstance(database, Database)
    return database


def frame_ids(node_id: int) -> dict[str, int]:
    return {pdo.name: pdo.cob_id(node_id) for pdo in TABLE.pdos if pdo.enabled and pdo.entries}


def test_writes_the_dbc_for_the_node_id_to_stdout(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, "dbc", "--node-id", "0x20")
    assert (code, err) == (0, "")
    database = load(out)
    assert {m.name: m.frame_id for m in database.messages} == frame_ids(0x20)
    assert database.get_message_by_name("TPDO1").frame_id == cob_id(FunctionCode.TPDO1, 0x20)
    assert run(capsys, "dbc", "-n", "32")[1] == out  # decimal and hex alike


def test_without_a_node_id_the_dbc_is_the_tables_default(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "dbc")
    assert code == 0
    assert {m.name: m.frame_id for m in load(out).messages} == frame_ids(TABLE.node.default_node_id)


def test_writes_the_file_whole_and_says_so(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    target = tmp_path / "dbc" / "board-33.dbc"
    target.parent.mkdir()  # a folder that does not exist is refused (rig/tests/test_cli_refusals.py)
    code, out, err = run(capsys, "dbc", "--node-id", "33", "-o", str(target))
    assert (code, out) == (0, "")
    assert err == f"hilrig dbc: wrote {target}: {len(frame_ids(33))} PDO frames of node 0x21\n"
    assert {m.name: m.frame_id for m in load(target.read_text()).messages} == frame_ids(33)
    assert [p.name for p in target.parent.iterdir()] == ["board-33.dbc"]  # no temporary file left


@pytest.mark.parametrize("text", ["0", "128", "0x80", "-1", "abc", "0x", "1.5"])
def test_a_bad_node_id_is_one_line_exit_code_2(capsys: pytest.CaptureFixture[str], text: str) -> None:
    code, out, err = run(capsys, "dbc", "--node-id", text)
    assert (code, out) == (2, "")
    assert err.count("\n") == 1, f"expected one line, got {err!r}"
    assert err.startswith("hilrig dbc: error: argument -n/--node-id: expected a node id 1..127")


def test_a_bad_table_is_one_line_exit_code_2(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    bad = tmp_path / "board.toml"
    bad.write_text("[node]\n")
    code, out, err = run(capsys, "dbc", "--table", str(bad))
    assert (code, out) == (2, "")
    assert err.startswith(f"hilrig dbc: error: {bad}: node: missing keys")
    assert err.count("\n") == 1


def test_a_node_id_above_63_warns_that_pdo_5_to_8_take_another_nodes_ids(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code, out, err = run(capsys, "dbc", "--node-id", "0x50")
    assert code == 0
    rpdo1_of_node_0x10 = cob_id(FunctionCode.RPDO1, 0x10)
    assert load(out).get_message_by_name("TPDO5").frame_id == rpdo1_of_node_0x10
    assert err.count("\n") == 1
    assert err.startswith("hilrig dbc: warning: node id 0x50 is above 63")
    assert "TPDO5 0x210 = RPDO1 of node 0x10" in err
    assert run(capsys, "dbc", "--node-id", "63")[2] == ""


def test_a_candump_log_decodes_to_the_named_values(capsys: pytest.CaptureFixture[str]) -> None:
    """The generated DBC for node 0x20 on a candump log, read as cantools' own decoder reads it."""
    _, out, _ = run(capsys, "dbc", "--node-id", "0x20")
    database = load(out)
    log = io.StringIO(
        "(1700000000.000000) can0 420#0000803F00000000\n"  # RPDO3 of node 0x20: control_mode 1.0
        "(1700000000.001000) can0 2E0#0000803F00000040\n"  # TPDO6: safe_state 1.0, fault_flags 2.0
        "(1700000000.002000) can0 1A0#000001\n"  # TPDO1: motor_duty 0, led_pattern 1
    )
    decoded = [
        database.decode_message(frame.frame_id, frame.data) for frame in cantools.logreader.Parser(log)
    ]
    assert [{k: str(v) for k, v in values.items()} for values in decoded] == [
        {"control_mode": "velocity", "position_setpoint": "0.0"},
        {"safe_state": "1.0", "fault_flags": "output_encoder_stale"},
        {"motor_duty": "0", "led_pattern": "on"},
    ]


def test_the_console_command_prints_a_dbc_cantools_decode_reads(tmp_path: Path) -> None:
    result = subprocess.run(
        [*HILRIG, "dbc", "-n", "0x7"], capture_output=True, text=True, check=False, timeout=60
    )
    assert (result.returncode, result.stderr) == (0, "")
    assert {m.name: m.frame_id for m in load(result.stdout).messages} == frame_ids(7)
    dbc = tmp_path / "board-7.dbc"
    dbc.write_text(result.stdout)
    decode = subprocess.run(
        [sys.executable, "-m", "cantools", "decode", "--single-line", str(dbc)],
        input="(1700000000.000000) can0 407#0000803F0000803F\n",  # RPDO3 of node 7
        capture_output=True,
        text=True,
        check=True,
        timeout=60,
    )
    assert "RPDO3(control_mode: velocity, position_setpoint: 1.0 rad)" in decode.stdout
