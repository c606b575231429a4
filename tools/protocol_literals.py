"""Find protocol values typed by hand: COB-ID bases, fault bits, control-mode numbers, EMCY codes.

Each has one home: the CiA 301 connection set in `boardproto.cia301`, the board's named values
(control modes, fault bits, LED patterns, EMCY codes) in protocol/board.toml, reached in Python
through `hilrig.table` (`ControlMode.VELOCITY`, `FaultFlags.MOTOR_ENCODER_STALE`,
`EmcyCode.STALE_SENSOR`). A number typed anywhere else is a second copy that nothing checks.

    python tools/protocol_literals.py            # lists findings, exit 1 if any
    python tools/protocol_literals.py rig/x.py   # only these files (or directories)

What counts, in rig/, tests/ and tools/ (Python):
- a hex literal equal to a COB-ID base of the predefined connection set (0x080, 0x180 ... 0x700)
  or of the form base + node id written with three hex digits (0x190, 0x610, 0x710);
- a hex literal equal to an EMCY code the table declares (0x5000, 0x8210, ...);
- a number other than 0 in an expression that is about fault flags (a name, attribute or string
  with "fault_flags", "fault_bit" or "fault_mask" in it: `fault_flags & 3`, `FAULT_BIT = 1 << 4`);
- a number in an expression that is about the control mode (`rig.set("control_mode", 1)`,
  `control_mode == 2`, `VELOCITY_MODE = 1`).

A deliberate literal (a test that spells the wire bytes on purpose, a byte that merely equals a
base) is marked on its line with `# protocol-literal: <why>`; the reason is required.
"""

from __future__ import annotations

import ast
import sys
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "protocol"))

from boardproto import load_table  # noqa: E402
from boardproto.cia301 import FunctionCode  # noqa: E402

SCANNED_DIRECTORIES = ("rig", "tests", "tools")
MARKER = "# protocol-literal:"
THIS_FILE = Path(__file__).resolve()

# NMT's COB-ID is 0: a literal 0 is far too common to flag; NMT frames are spelled NMT_COB_ID.
COB_ID_BASES = frozenset(int(code) for code in FunctionCode if code != FunctionCode.NMT)
PER_NODE_BASES = COB_ID_BASES - {int(FunctionCode.TIME)}  # TIME has no node id
NODE_ID_MASK = 0x7F
# Words that make an expression about the control mode / the fault flags.
CONTROL_MODE_WORDS = ("control_mode", "velocity_mode", "torque_mode", "position_mode", "disabled_mode")
FAULT_WORDS = ("fault_flags", "fault_bit", "fault_mask", "fault_flag")
FAULT_SUFFIXES = ("_bit", "_flags")  # COMMAND_WATCHDOG_BIT = 1 << 4, STALE_ENCODER_FLAGS = 0b11


@dataclass(frozen=True)
class Finding:
    path: Path
    line: int
    text: str
    why: str

    def __str__(self) -> str:
        try:
            shown = self.path.relative_to(REPO)
        except ValueError:
            shown = self.path
        return f"{shown}:{self.line}: {self.text!r}: {self.why}"


def _emcy_codes() -> frozenset[int]:
    table = load_table(REPO / "protocol" / "board.toml")
    return frozenset(code.code for code in table.emcy_codes)


def _is_cob_id(value: int, spelled: str) -> bool:
    if value in COB_ID_BASES:
        return True
    digits = spelled[2:].replace("_", "")
    return len(digits) == 3 and (value & ~NODE_ID_MASK) in PER_NODE_BASES and value & NODE_ID_MASK != 0


def _words(node: ast.AST) -> Iterator[str]:
    """Lower-case names, attributes and strings that appear in an expression, except inside a
    subscript's index (`x[paths["control_mode"]]` is not about the mode's value) and a dict
    (its own context: each key goes with its value)."""
    if isinstance(node, ast.Name):
        yield node.id.lower()
    elif isinstance(node, ast.Attribute):
        yield node.attr.lower()
    elif isinstance(node, ast.Constant) and isinstance(node.value, str):
        yield node.value.lower()
    elif isinstance(node, ast.keyword) and node.arg:
        yield node.arg.lower()
    if isinstance(node, ast.Subscript):
        yield from _words(node.value)
        return
    if isinstance(node, ast.Dict):
        return
    for child in ast.iter_child_nodes(node):
        yield from _words(child)


def _numbers(node: ast.AST) -> Iterator[ast.Constant]:
    """Number literals of an expression, except subscripts and slices (indexes, not values)."""
    if isinstance(node, ast.Subscript):
        yield from _numbers(node.value)
        return
    if isinstance(node, ast.Dict):
        return  # a context of its own
    if isinstance(node, ast.Constant):
        if isinstance(node.value, int | float) and not isinstance(node.value, bool):
            yield node
        return
    for child in ast.iter_child_nodes(node):
        yield from _numbers(child)


def _about(words: Iterable[str]) -> str | None:
    words = list(words)
    if any(key in w for w in words for key in CONTROL_MODE_WORDS):
        return "control mode"
    if any(key in w for w in words for key in FAULT_WORDS) or any(w.endswith(FAULT_SUFFIXES) for w in words):
        return "fault flags"
    return None


# Expressions small enough that a number in them is a value of the thing they name.
_VALUE_CONTEXTS = (ast.Compare, ast.BinOp, ast.Call, ast.Assign, ast.AnnAssign, ast.Dict)


class _Scanner(ast.NodeVisitor):
    def __init__(self, path: Path, source: str, emcy_codes: frozenset[int]) -> None:
        self.path = path
        self.lines = source.split("\n")  # as the parser counts lines
        self.encoded_lines = [line.encode() for line in self.lines]  # AST columns count UTF-8 bytes
        self.source = source
        self.emcy_codes = emcy_codes
        self.findings: dict[tuple[int, int], Finding] = {}

    def _spelled(self, node: ast.Constant) -> str:
        """The literal as written (ast.get_source_segment re-splits the file on every call)."""
        if node.end_lineno != node.lineno or node.end_col_offset is None:
            return ""
        line = self.encoded_lines[node.lineno - 1]
        return line[node.col_offset : node.end_col_offset].decode("utf-8", "replace")

    def _add(self, node: ast.Constant, why: str) -> None:
        line = self.lines[node.lineno - 1]
        if MARKER in line:
            if line.split(MARKER, 1)[1].strip():
                return
            why = f"{why} (the {MARKER!r} mark on this line gives no reason)"
        text = self._spelled(node) or repr(node.value)
        self.findings.setdefault((node.lineno, node.col_offset), Finding(self.path, node.lineno, text, why))

    def visit_Constant(self, node: ast.Constant) -> None:
        if isinstance(node.value, int) and not isinstance(node.value, bool):
            spelled = self._spelled(node)
            if spelled.lower().startswith("0x"):
                if _is_cob_id(node.value, spelled):
                    self._add(node, "a COB-ID of the CiA 301 connection set: use boardproto.cia301")
                elif node.value in self.emcy_codes:
                    self._add(node, "an EMCY code of board.toml: use hilrig.table.EmcyCode")

    def generic_visit(self, node: ast.AST) -> None:
        if isinstance(node, _VALUE_CONTEXTS):
            self._check_values(node)
        super().generic_visit(node)

    def _check_values(self, node: ast.AST) -> None:
        for words, numbers in _value_groups(node):
            about = _about(words)
            if about is None:
                continue
            for number in numbers:
                if number.value == 0 and about == "fault flags":
                    continue  # no fault
                if about == "control mode":
                    self._add(number, "a control-mode number: use hilrig.table.ControlMode")
                else:
                    self._add(number, "a fault bit or mask: use hilrig.table.FaultFlags")


def _direct_number(node: ast.AST) -> ast.Constant | None:
    if isinstance(node, ast.UnaryOp):
        node = node.operand
    if (
        isinstance(node, ast.Constant)
        and isinstance(node.value, int | float)
        and not isinstance(node.value, bool)
    ):
        return node
    return None


def _value_groups(node: ast.AST) -> Iterator[tuple[list[str], list[ast.Constant]]]:
    """(words, numbers) that belong together in `node`: a number is a value of what is named
    beside it. A call pairs only its direct arguments (set("control_mode", 1)), so a number deep
    in one argument is not taken for a value of a name in another; a dict pairs key and value."""
    if isinstance(node, ast.Call):
        arguments = [*node.args, *(k.value for k in node.keywords)]
        words = [k.arg.lower() for k in node.keywords if k.arg]
        for argument in arguments:
            if isinstance(argument, ast.Name | ast.Attribute | ast.Constant):
                words += _words(argument)
        numbers = [n for n in map(_direct_number, arguments) if n is not None]
        yield words, numbers
    elif isinstance(node, ast.Assign | ast.AnnAssign):
        # NAME = 1 << 4; a call on the right is a context of its own
        targets = node.targets if isinstance(node, ast.Assign) else [node.target]
        if node.value is not None and not isinstance(node.value, ast.Call):
            yield [w for t in targets for w in _words(t)], [*_numbers(node.value)]
    elif isinstance(node, ast.Dict):
        for key, value in zip(node.keys, node.values, strict=True):
            if key is not None:
                yield [*_words(key)], [*_numbers(value)]
    else:
        yield [*_words(node)], [*_numbers(node)]


def scan_file(path: Path, emcy_codes: frozenset[int] | None = None) -> list[Finding]:
    source = path.read_text(encoding="utf-8")
    scanner = _Scanner(path, source, _emcy_codes() if emcy_codes is None else emcy_codes)
    scanner.visit(ast.parse(source, filename=str(path)))
    return sorted(scanner.findings.values(), key=lambda f: f.line)


def scanned_files(root: Path = REPO) -> list[Path]:
    files = []
    for directory in SCANNED_DIRECTORIES:
        files += sorted((root / directory).rglob("*.py"))
    return [f for f in files if f.resolve() != THIS_FILE and "__pycache__" not in f.parts]


def scan(paths: Iterable[Path]) -> list[Finding]:
    codes = _emcy_codes()
    return [finding for path in paths for finding in scan_file(path, codes)]


def main(argv: list[str]) -> int:
    paths = [p for a in argv for p in (sorted(Path(a).rglob("*.py")) if Path(a).is_dir() else [Path(a)])]
    paths = paths or scanned_files()
    findings = scan(paths)
    for finding in findings:
        print(finding)
    if findings:
        print(
            f"{len(findings)} protocol value(s) typed by hand; import them, or mark a deliberate "
            f"one with '{MARKER} <why>'",
            file=sys.stderr,
        )
    return 1 if findings else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
