"""hilrig.resources from a checkout: the checkout's table and build tree, and the EDS and DBC of
another table (--table) generated on the fly. The installed case: test_wheel.py."""

from __future__ import annotations

import os
from pathlib import Path

import can
import pytest

from boardproto import load_table
from boardproto.dbc import generate_dbc
from hilrig import resources
from hilrig.cli import main
from hilrig.table import BOARD_TABLE

REPO = Path(__file__).resolve().parents[2]
RENAMED = "motor_pwm"
"""hil_output motor_duty renamed in the other table: a name only that table's DBC knows."""


@pytest.fixture
def other_table(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    path = tmp_path / "other-board.toml"
    path.write_text((REPO / "protocol" / "board.toml").read_text().replace('"motor_duty"', f'"{RENAMED}"'))
    return path


def test_a_checkout_uses_its_table_and_what_make_build_generated() -> None:
    assert resources.CHECKOUT == REPO
    assert resources.DEFAULT_TABLE == REPO / "protocol" / "board.toml"
    default = resources.board_files()
    built = REPO / "build" / "protocol"
    assert (default.eds, default.dbc) == (built / "board.eds", built / "board.dbc")
    relative = Path(os.path.relpath(resources.DEFAULT_TABLE))  # --table protocol/board.toml
    assert resources.board_files(relative) == default
    assert "make build" in resources.EDS_HINT


def test_another_table_gets_its_eds_and_dbc_generated_into_the_cache(
    other_table: Path, tmp_path: Path
) -> None:
    files = resources.board_files(other_table)
    assert files.eds.parent == files.dbc.parent
    assert files.eds.parent.parent == tmp_path / "cache" / "hilrig" / "tables"
    assert files.dbc.read_bytes() == generate_dbc(load_table(other_table)).encode()
    assert f"ParameterName={RENAMED}" in files.eds.read_text()
    written = files.dbc.stat().st_mtime_ns
    assert resources.board_files(other_table) == files
    assert files.dbc.stat().st_mtime_ns == written, "unchanged text: not rewritten"
    other_table.write_text(other_table.read_text().replace(f'"{RENAMED}"', '"motor_pwm_out"'))
    assert resources.board_files(other_table).dbc.parent != files.dbc.parent, "another table, another place"


def test_a_cache_that_exists_read_only_falls_back_to_the_temporary_directory(
    other_table: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The micro-VM mounts the home read-only: ~/.cache/hilrig/tables is there (made natively)
    # but cannot take a file. Root writes through modes, so the mount is stood in for by access().
    cache = tmp_path / "cache" / "hilrig" / "tables"
    cache.mkdir(parents=True)
    real_access = os.access

    def access(path: str | Path, mode: int) -> bool:
        return False if Path(path) == cache else real_access(path, mode)

    monkeypatch.setattr(resources.os, "access", access)
    monkeypatch.setattr(resources.tempfile, "tempdir", str(tmp_path / "tmp"))
    files = resources.board_files(other_table)
    assert files.eds.parent.parent == tmp_path / "tmp" / f"hilrig-{os.getuid()}" / "tables"
    assert f"ParameterName={RENAMED}" in files.eds.read_text()
    assert list(cache.iterdir()) == []


def test_replay_decode_with_another_table_uses_the_dbc_generated_for_it(
    other_table: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = tmp_path / "bus.log"
    tpdo1 = BOARD_TABLE.tpdo(1).cob_id(BOARD_TABLE.node.default_node_id)
    with can.Logger(str(log)) as logger:
        logger(can.Message(timestamp=1.0, arbitration_id=tpdo1, data=bytes(3), is_extended_id=False))
    assert main(["replay", str(log), "--decode", "--table", str(other_table)]) == 0
    out = capsys.readouterr().out
    assert f"TPDO1  {RENAMED}=0 0.01%" in out
    assert main(["replay", str(log), "--decode"]) == 0
    assert "TPDO1  motor_duty=0 0.01%" in capsys.readouterr().out
