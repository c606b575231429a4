"""The engine knows no board: what it streams and watches comes from the table and the plant, so
no string in `rig/hilrig/engine/` code is the name of a field or HIL object of any board table
in the tree (the demo joint's, the head's, the examples'). Docstrings may show usage on the
demo's names; code may not. The check is tried on a small example both ways, so it cannot pass
by finding nothing."""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

from boardproto.loader import load_table

ROOT = Path(__file__).resolve().parents[2]
ENGINE = ROOT / "rig" / "hilrig" / "engine"
TABLES = sorted(
    [
        ROOT / "protocol" / "board.toml",
        *(ROOT / "protocol" / "boards").glob("*.toml"),
        *ROOT.glob("examples/*/board.toml"),
    ]
)


def board_names() -> frozenset[str]:
    """Every field and HIL object name of every board table in the tree."""
    names: set[str] = set()
    for path in TABLES:
        names.update(entry.name for entry in load_table(path).entries)
    return frozenset(names)


def _docstrings(tree: ast.AST) -> set[int]:
    """ids of the string constants that are docstrings (a module's, a class's, a function's, and
    an attribute's: a string statement after an assignment)."""
    found: set[int] = set()
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if not isinstance(body, list):
            continue
        for statement in body:
            if isinstance(statement, ast.Expr) and isinstance(statement.value, ast.Constant):
                found.add(id(statement.value))
    return found


def named_fields(source: str, names: frozenset[str]) -> Iterator[tuple[int, str]]:
    """(line, name) of each string constant in `source`'s code that is one of `names`."""
    tree = ast.parse(source)
    docstrings = _docstrings(tree)
    for node in ast.walk(tree):
        is_string = isinstance(node, ast.Constant) and isinstance(node.value, str)
        if is_string and id(node) not in docstrings and node.value in names:
            yield node.lineno, node.value


def test_the_check_finds_a_field_named_in_code_and_not_one_in_a_docstring() -> None:
    source = '"""rig.set("velocity_setpoint", 1.0)"""\nSTREAM = ("velocity_setpoint", "other")\n'
    assert list(named_fields(source, frozenset({"velocity_setpoint"}))) == [(2, "velocity_setpoint")]
    assert list(named_fields('"""velocity_setpoint"""\n', frozenset({"velocity_setpoint"}))) == []


def test_the_tables_are_found_and_name_the_demo_fields() -> None:
    names = board_names()
    assert {"velocity_setpoint", "motor_duty", "fault_flags"} <= names
    assert len(TABLES) >= 3, TABLES


def test_the_engine_names_no_board_field() -> None:
    names = board_names()
    found = [
        f"{path.relative_to(ROOT)}:{line}: {name!r}"
        for path in sorted(ENGINE.glob("*.py"))
        for line, name in named_fields(path.read_text(), names)
    ]
    fix = "take them from the table or the plant"
    assert found == [], f"the engine names board fields ({fix}):\n" + "\n".join(found)
