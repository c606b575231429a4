"""`python -m boardproto generate`: outputs, write-only-on-change, errors, --help."""

from __future__ import annotations

import csv
import os
import subprocess
import sys
from pathlib import Path

from boardproto import BoardTable
from boardproto.cli import main

PROTOCOL_DIR = Path(__file__).resolve().parents[1]
OUTPUT_FILES = ("include/board/fields.hpp", "board.eds", "board.dbc", "field_vectors.csv")


def run_cli(*arguments: str) -> subprocess.CompletedProcess[str]:
    environment = {**os.environ, "PYTHONPATH": str(PROTOCOL_DIR)}
    return subprocess.run(
        [sys.executable, "-m", "boardproto", *arguments],
        capture_output=True,
        text=True,
        env=environment,
        check=False,
    )


def test_generate_writes_every_output(tmp_path: Path) -> None:
    result = run_cli("generate", "--table", str(PROTOCOL_DIR / "board.toml"), "--out-dir", str(tmp_path))
    assert result.returncode == 0, result.stderr
    assert all((tmp_path / name).is_file() for name in OUTPUT_FILES)
    assert not [p for p in tmp_path.rglob(".*") if p.is_file()], "temporary files left behind"


def test_unchanged_outputs_are_not_rewritten(tmp_path: Path, minimal_table: str) -> None:
    table_path = tmp_path / "board.toml"
    table_path.write_text(minimal_table)
    out_dir = tmp_path / "out"
    assert main(["generate", "--table", str(table_path), "--out-dir", str(out_dir)]) == 0
    for name in OUTPUT_FILES:
        os.utime(out_dir / name, ns=(1, 1))  # a rewrite would reset this
    assert main(["generate", "--quiet", "--table", str(table_path), "--out-dir", str(out_dir)]) == 0
    assert [(out_dir / name).stat().st_mtime_ns for name in OUTPUT_FILES] == [1, 1, 1, 1]

    mtime = table_path.stat().st_mtime_ns  # keep the EDS date: only the description changes
    table_path.write_text(minimal_table.replace('description = "Gain"', 'description = "Kp"'))
    os.utime(table_path, ns=(mtime, mtime))
    assert main(["generate", "--quiet", "--table", str(table_path), "--out-dir", str(out_dir)]) == 0
    assert "Kp" in (out_dir / "include/board/fields.hpp").read_text()
    assert (out_dir / "field_vectors.csv").stat().st_mtime_ns == 1  # has no descriptions


def test_bad_table_prints_one_line_and_exits_2(tmp_path: Path, minimal_table: str) -> None:
    table_path = tmp_path / "board.toml"
    table_path.write_text(minimal_table.replace('kind = "sensor"', 'kind = "sensr"'))
    result = run_cli("generate", "--table", str(table_path), "--out-dir", str(tmp_path / "out"))
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1, result.stderr
    assert result.stderr.startswith(f"boardproto: error: {table_path}: field 'motor_position': ")
    assert not (tmp_path / "out").exists()


def test_help_explains_the_outputs() -> None:
    result = run_cli("generate", "--help")
    assert result.returncode == 0
    for name in (*OUTPUT_FILES, "--table", "--out-dir"):
        assert name in result.stdout


def test_field_vectors_are_the_parsed_table(generated_dir: Path, table: BoardTable) -> None:
    with (generated_dir / "field_vectors.csv").open(newline="") as file:
        rows = list(csv.DictReader(file))
    assert [row["name"] for row in rows] == list(table.field_names)
    for row, field in zip(rows, table.fields, strict=True):
        assert int(row["index"], 16) == field.index
        assert (row["unit"], row["kind"], row["access"]) == (
            field.unit,
            field.kind.value,
            field.access.value,
        )
        assert float(row["min"]) == field.min
        assert float(row["max"]) == field.max
        assert float(row["default"]) == field.default
        assert row["stored"] == ("1" if field.stored else "0")
