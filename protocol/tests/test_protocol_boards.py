"""More than one board: every table under protocol/boards/ (the robot head module's...) loads
beside the joint's protocol/board.toml, generates the same set of files, names itself in them, and
its EDS opens in canopen with its identity and every field."""

from __future__ import annotations

from pathlib import Path

import pytest
from canopen.objectdictionary import import_od

from boardproto import load_table
from boardproto.cli import OUTPUTS, generate
from boardproto.cpp_header import banner, table_name

PROTOCOL_DIR = Path(__file__).resolve().parents[1]
BOARD_TABLES = sorted((PROTOCOL_DIR / "boards").glob("*.toml"))


def test_the_head_is_one_of_the_boards() -> None:
    assert PROTOCOL_DIR / "boards" / "head.toml" in BOARD_TABLES


@pytest.mark.parametrize("path", BOARD_TABLES, ids=lambda path: path.stem)
def test_board_generates_every_output_naming_its_table(path: Path, tmp_path: Path) -> None:
    table = load_table(path)
    generate(path, tmp_path)
    assert {str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*") if p.is_file()} == set(OUTPUTS)
    assert table_name(table) == f"protocol/boards/{path.name}"
    assert (tmp_path / "include/board/fields.hpp").read_text().startswith(banner(table) + "\n")

    od = import_od(str(tmp_path / "board.eds"), node_id=table.node.default_node_id)
    assert od[0x1018][2].default == table.node.product_code
    for field in table.fields:
        assert od[field.index].name == field.name


def test_boards_differ_from_the_joint_in_identity() -> None:
    joint = load_table(PROTOCOL_DIR / "board.toml")
    for path in BOARD_TABLES:
        other = load_table(path)
        assert other.node.product_code != joint.node.product_code, path.name
        assert table_name(joint) == "protocol/board.toml"
