"""Find protocol values typed by hand: COB-ID bases, SDO abort codes, fault bits, control-mode
numbers, EMCY codes.

Each has one home: the CiA 301 rules (connection set, abort codes) in `boardproto.cia301`, which
the firmware reaches through the generated `board/cia301.hpp`; the board's named values (control
modes, fault bits, LED patterns, EMCY codes) in protocol/board.toml, reached in Python through
`hilrig.table` (`ControlMode.VELOCITY`, `FaultFlags.MOTOR_ENCODER_STALE`, `EmcyCode.STALE_SENSOR`)
and in C++ through `board/fields.hpp`. A number typed anywhere else is a second copy that nothing
checks.

    python tools/protocol_literals.py            # lists findings, exit 1 if any
    python tools/protocol_literals.py rig/x.py   # only these files (or directories)

What counts, in the Python, C and C++ of firmware/, protocol/, rig/, tests/ and tools/ (the home,
protocol/boardproto/cia301.py, excepted):
- a hex literal equal to a COB-ID base of the predefined connection set (0x080, 0x180 ... 0x700)
  or of the form base + node id written with three hex digits (0x190, 0x610, 0x710);
- a hex literal equal to an SDO abort code (0x06090031, in C++ also 0x0609'0031), except in the
  bus-level scenarios of tests/: its CiA 301 conformance checks spell the spec's codes on
  purpose, a reading of the spec independent of boardproto.cia301;
- a hex literal equal to an EMCY code the table declares (0x5000, 0x8210, ...);
and in the Python of rig/, tests/ and tools/ (protocol/ is where the board's named values are
defined and generated, and its tests read the generated files back against numbers):
- a number other than 0 in an expression that is about fault flags (a name, attribute or string
  with "fault_flags", "fault_bit" or "fault_mask" in it: `fault_flags & 3`, `FAULT_BIT = 1 << 4`);
- a number in an expression that is about the control mode (`rig.set("control_mode", 1)`,
  `control_mode == 2`, `VELOCITY_MODE = 1`).
The last two read Python's syntax tree. C and C++ are read as text, comments and string literals
left out, for the CiA 301 rules only (the board's named values reach C++ through the generated
board/fields.hpp, whose cross-check is protocol/tests/FieldTableTest.cpp): an abort code in any
spelling, a COB-ID written with three hex digits (0x080, 0x610) or a base added to something
(`0x80 + node_id`); a two-digit 0x80 alone is a byte there (a command specifier, bit 7).

A deliberate literal (a test that spells the wire bytes on purpose, a byte that merely equals a
base) is marked on its line with `# protocol-literal: <why>` (C/C++: `// protocol-literal: <why>`);
the reason is required.
"""

from __future__ import annotations

import ast
import re
import sys
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "protocol"))

from boardproto import load_table  # noqa: E402
from boardproto.cia301 import FunctionCode, SdoAbortCode  # noqa: E402
from boardproto.cia305 import MASTER_COB_ID, SLAVE_COB_ID  # noqa: E402

SCANNED_DIRECTORIES = ("firmware", "protocol", "rig", "tests", "tools")
PYTHON_SUFFIXES = (".py",)
C_SUFFIXES = (".c", ".h", ".cpp", ".hpp")
MARKER_TEXT = "protocol-literal:"
MARKER = f"# {MARKER_TEXT}"
C_MARKER = f"// {MARKER_TEXT}"
THIS_FILE = Path(__file__).resolve()
HOMES = frozenset(
    {REPO / "protocol" / "boardproto" / "cia301.py", REPO / "protocol" / "boardproto" / "cia305.py"}
)
"""Files that are the home of the values: they state them, nothing to find there."""
NAMED_VALUE_DIRECTORIES = ("rig", "tests", "tools")
"""Where the control-mode and fault-flag rules apply (the board's named values' users)."""
SPEC_CONFORMANCE_DIRECTORIES = ("tests",)
"""Where SDO abort codes may be spelled: the conformance scenarios check against the spec."""

# NMT's COB-ID is 0: a literal 0 is far too common to flag; NMT frames are spelled NMT_COB_ID.
COB_ID_BASES = frozenset(int(code) for code in FunctionCode if code != FunctionCode.NMT)
PER_NODE_BASES = COB_ID_BASES - {int(FunctionCode.TIME)}  # TIME has no node id
LSS_COB_IDS = frozenset({MASTER_COB_ID, SLAVE_COB_ID})  # CiA 305, boardproto.cia305
NODE_ID_MASK = 0x7F
# Words that make an expression about the control mode / the fault flags.
CONTROL_MODE_WORDS = ("control_mode", "velocity_mode", "torque_mode", "position_mode", "disabled_mode")
FAULT_WORDS = ("fault_flags", "fault_bit", "fault_mask", "fault_flag")
FAULT_SUFFIXES = ("_bit", "_flags")  # COMMAND_WATCHDOG_BIT = 1 << 4, STALE_ENCODER_FLAGS = 0b11
SDO_ABORT_CODES = frozenset(int(code) for code in SdoAbortCode)
WHY_COB_ID = "a COB-ID of the CiA 301 connection set: use boardproto.cia301"
WHY_COB_ID_CPP = "a COB-ID of the CiA 301 connection set: use cia301:: of board/cia301.hpp"
WHY_SDO_ABORT = "an SDO abort code: use boardproto.cia301.SdoAbortCode"
WHY_SDO_ABORT_CPP = "an SDO abort code: use cia301::SdoAbort of board/cia301.hpp"
WHY_EMCY = "an EMCY code of board.toml: use hilrig.table.EmcyCode"


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
    if value in COB_ID_BASES or value in LSS_COB_IDS:
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


@dataclass(frozen=True)
class _Rules:
    """Which rules apply to a file besides the COB-ID and EMCY ones (those apply everywhere)."""

    sdo_abort_codes: bool
    named_values: bool


def _rules_for(path: Path) -> _Rules:
    """A file of the repository by its top folder; any other file (an example) gets every rule."""
    try:
        top = path.resolve().relative_to(REPO).parts[0]
    except ValueError:
        return _Rules(sdo_abort_codes=True, named_values=True)
    return _Rules(
        sdo_abort_codes=top not in SPEC_CONFORMANCE_DIRECTORIES,
        named_values=top in NAMED_VALUE_DIRECTORIES,
    )


class _Scanner(ast.NodeVisitor):
    def __init__(self, path: Path, source: str, emcy_codes: frozenset[int], rules: _Rules) -> None:
        self.path = path
        self.rules = rules
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
                    self._add(node, WHY_COB_ID)
                elif self.rules.sdo_abort_codes and node.value in SDO_ABORT_CODES:
                    self._add(node, WHY_SDO_ABORT)
                elif node.value in self.emcy_codes:
                    self._add(node, WHY_EMCY)

    def generic_visit(self, node: ast.AST) -> None:
        if self.rules.named_values and isinstance(node, _VALUE_CONTEXTS):
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


# C and C++ text: comments and string/character literals are blanked (newlines kept, so line
# numbers stay), then hex literals are read with their digit separators and suffixes.
_C_NOT_CODE = re.compile(
    r"""//[^\n]*|/\*.*?\*/|"(?:\\.|[^"\\\n])*"|'(?:\\.|[^'\\\n])+'(?![0-9A-Fa-f])""", re.DOTALL
)
_C_HEX = re.compile(r"(?<![\w.'])0[xX][0-9A-Fa-f](?:'?[0-9A-Fa-f])*[uUlL]*\b")
_C_ADDED_AFTER = re.compile(r"^\s*\+(?!\+)")  # `0x80 + id`
_C_ADDED_BEFORE = re.compile(r"(?<!\+)\+\s*$")  # `id + 0x80`


def _blank(match: re.Match[str]) -> str:
    return re.sub(r"[^\n]", " ", match.group(0))


def scan_c_source(path: Path, source: str) -> list[Finding]:
    """Findings in C or C++ text: the CiA 301 hex-literal rules (a comment may name any code)."""
    lines = source.split("\n")
    code = _C_NOT_CODE.sub(_blank, source)
    findings = []
    for number, line in enumerate(code.split("\n"), start=1):
        for match in _C_HEX.finditer(line):
            spelled = match.group(0).rstrip("uUlL").replace("'", "")
            value = int(spelled, 16)
            added = _C_ADDED_AFTER.search(line[match.end() :][:3]) or _C_ADDED_BEFORE.search(
                line[: match.start()][-3:]
            )
            if _is_cob_id(value, spelled) and (len(spelled) == 5 or added):
                why = WHY_COB_ID_CPP
            elif value in SDO_ABORT_CODES and _rules_for(path).sdo_abort_codes:
                why = WHY_SDO_ABORT_CPP
            else:
                continue
            original = lines[number - 1]
            if C_MARKER in original:
                if original.split(C_MARKER, 1)[1].strip():
                    continue
                why = f"{why} (the {C_MARKER!r} mark on this line gives no reason)"
            findings.append(Finding(path, number, match.group(0), why))
    return findings


def scan_file(path: Path, emcy_codes: frozenset[int] | None = None) -> list[Finding]:
    source = path.read_text(encoding="utf-8")
    codes = _emcy_codes() if emcy_codes is None else emcy_codes
    if path.suffix in C_SUFFIXES:
        return scan_c_source(path, source)
    scanner = _Scanner(path, source, codes, _rules_for(path))
    scanner.visit(ast.parse(source, filename=str(path)))
    return sorted(scanner.findings.values(), key=lambda f: f.line)


def _is_scanned(path: Path) -> bool:
    return path.suffix in PYTHON_SUFFIXES + C_SUFFIXES and "__pycache__" not in path.parts


def scanned_files(root: Path = REPO) -> list[Path]:
    files = []
    for directory in SCANNED_DIRECTORIES:
        files += sorted(f for f in (root / directory).rglob("*") if _is_scanned(f))
    skipped = {THIS_FILE, *(home.resolve() for home in HOMES)}
    return [f for f in files if f.resolve() not in skipped]


def scan(paths: Iterable[Path]) -> list[Finding]:
    codes = _emcy_codes()
    return [finding for path in paths for finding in scan_file(path, codes)]


def main(argv: list[str]) -> int:
    paths = [
        path
        for argument in map(Path, argv)
        for path in (sorted(filter(_is_scanned, argument.rglob("*"))) if argument.is_dir() else [argument])
    ]
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
