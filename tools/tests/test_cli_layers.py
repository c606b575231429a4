"""The command line stays thin, checked from the source: no module of rig/hilrig/cli imports
python-can or canopen (at the top, inside a function, under TYPE_CHECKING: a deferred import is
still frame-level work in the CLI), and none produces SYNC itself (the counter rule `% 240` or
`sync_counter`, a SYNC producer class): the bus is opened by `hilrig.session.canbus`, NMT and
SYNC go through `hilrig.wire.master` and `hilrig.engine.realtime.SyncProducer`, the one producer.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CLI = ROOT / "rig" / "hilrig" / "cli"

BANNED_PACKAGES = frozenset({"can", "canopen"})
"""Top-level packages the CLI must not import: the layers below it own the frames."""
SYNC_COUNTER_MODULI = (240, "SYNC_COUNTER_MAX")
"""`x % 240`, `x % SYNC_COUNTER_MAX`: the SYNC counter rule (`boardproto.cia301.sync_counter`)."""
SYNC_RULE_NAMES = frozenset({"sync_counter"})


@dataclass(frozen=True)
class Finding:
    module: str
    line: int
    what: str

    def __str__(self) -> str:
        return f"{self.module}:{self.line}: {self.what}"


def _banned(module: str | None) -> bool:
    return module is not None and module.split(".")[0] in BANNED_PACKAGES


def _modulus(node: ast.expr) -> int | str | None:
    if isinstance(node, ast.Constant) and isinstance(node.value, int):
        return node.value
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        return node.attr
    return None


def _is_text(node: ast.expr) -> bool:
    """'%d' % x is string formatting, not a modulo."""
    return isinstance(node, ast.JoinedStr) or (isinstance(node, ast.Constant) and isinstance(node.value, str))


def findings(source: str, module: str) -> list[Finding]:
    """What in `source` (the text of cli module `module`) breaks the CLI's layering."""
    found: list[Finding] = []
    for node in ast.walk(ast.parse(source, filename=module)):
        if isinstance(node, ast.Import):
            found += [Finding(module, node.lineno, f"import {a.name}") for a in node.names if _banned(a.name)]
        elif isinstance(node, ast.ImportFrom):
            if node.level == 0 and _banned(node.module):
                found.append(Finding(module, node.lineno, f"from {node.module} import ..."))
            found += [
                Finding(module, node.lineno, f"imports the SYNC counter rule {a.name}")
                for a in node.names
                if a.name in SYNC_RULE_NAMES
            ]
        elif isinstance(node, ast.Call):
            function = node.func
            name = function.attr if isinstance(function, ast.Attribute) else getattr(function, "id", None)
            argument = node.args[0] if node.args else None
            if (
                name in ("import_module", "__import__")
                and isinstance(argument, ast.Constant)
                and isinstance(argument.value, str)
                and _banned(argument.value)
            ):
                found.append(Finding(module, node.lineno, f"{name}({argument.value!r})"))
        elif isinstance(node, ast.BinOp) and isinstance(node.op, ast.Mod) and not _is_text(node.left):
            if _modulus(node.right) in SYNC_COUNTER_MODULI:
                found.append(
                    Finding(module, node.lineno, "a SYNC counter (% 240): the engine's SyncProducer counts")
                )
        elif (
            isinstance(node, ast.ClassDef) and "sync" in node.name.lower() and "producer" in node.name.lower()
        ):
            found.append(Finding(module, node.lineno, f"class {node.name}: a second SYNC producer"))
    return sorted(found, key=lambda f: f.line)


def cli_modules() -> list[Path]:
    return sorted(CLI.rglob("*.py"))


def test_the_check_sees_the_cli() -> None:
    names = {path.name for path in cli_modules()}
    assert {"__init__.py", "common.py", "nmt.py", "record.py", "scan.py", "watch.py"} <= names


@pytest.mark.parametrize("path", cli_modules(), ids=lambda path: path.name)
def test_no_cli_module_does_frame_level_work(path: Path) -> None:
    module = str(path.relative_to(ROOT))
    found = findings(path.read_text(encoding="utf-8"), module)
    assert not found, "the CLI parses, calls apps/session/wire and prints:\n" + "\n".join(map(str, found))


# --- the checker itself: each rule can fail --------------------------------------------------
BAD = """\
from __future__ import annotations
import can
from typing import TYPE_CHECKING
if TYPE_CHECKING:
    from canopen.emcy import EmcyError

def run():
    import canopen as co
    from can.interfaces import VALID_INTERFACES
    importlib.import_module("can.util")
    counter = 0
    counter = counter % 240 + 1
    return counter % cia301.SYNC_COUNTER_MAX

class SyncProducer:
    pass
"""


def test_the_checker_names_module_and_line_of_each_breach() -> None:
    assert [str(f) for f in findings(BAD, "cli/bad.py")] == [
        "cli/bad.py:2: import can",
        "cli/bad.py:5: from canopen.emcy import ...",
        "cli/bad.py:8: import canopen",
        "cli/bad.py:9: from can.interfaces import ...",
        "cli/bad.py:10: import_module('can.util')",
        "cli/bad.py:12: a SYNC counter (% 240): the engine's SyncProducer counts",
        "cli/bad.py:13: a SYNC counter (% 240): the engine's SyncProducer counts",
        "cli/bad.py:15: class SyncProducer: a second SYNC producer",
    ]


def test_the_checker_flags_the_counter_rule_imported() -> None:
    source = "from boardproto.cia301 import NmtState, sync_counter\n"
    assert [str(f) for f in findings(source, "m.py")] == [
        "m.py:1: imports the SYNC counter rule sync_counter"
    ]


def test_the_checker_leaves_the_layers_below_and_lookalikes_alone() -> None:
    good = (
        "import cantools\n"
        "import canopenish\n"
        "from . import canbus\n"
        "from hilrig.session.canbus import Bus, open_bus\n"
        "from hilrig.wire.master import BusMaster\n"
        "from hilrig.engine.realtime import SyncProducer\n"
        "percent = 7 % 100\n"
        "text = '%d' % 240\n"
    )
    # '%d' % 240 is string formatting of the number, not a counter modulo 240
    assert findings(good, "m.py") == []


def test_the_commands_help_loads_neither_python_can_nor_canopen() -> None:
    """`hilrig --help` and a command's --help build every parser: none of them may pull in the bus
    libraries (the layers below load them when a command talks to a bus), so they stay quick."""
    import subprocess
    import sys

    probe = (
        "import sys\n"
        "from hilrig.cli import main\n"
        "for argv in (['--help'], ['watch', '--help'], ['sdo', '--help']):\n"
        "    try:\n"
        "        main(argv)\n"
        "    except SystemExit:\n"
        "        pass\n"
        "print(sorted(m for m in ('can', 'canopen') if m in sys.modules))\n"
    )
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True, cwd=ROOT)
    assert done.stdout.strip().splitlines()[-1] == "[]", done.stdout[-500:]
