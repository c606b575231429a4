"""Realistic mutation operators for the firmware's C++, beside universalmutator's regexp rules:
the regressions a developer commits rather than every operator swapped.

- `drop condition`: one operand of a `&&`/`||` removed with its operator;
- `abs removed`: `std::fabs(x)`, `std::abs(x)` become `(x)`;
- `bound`: `>=` <-> `>`, `<=` <-> `<` (a threshold's neighbour);
- `same-type variable`: a use of a variable replaced by another of the same declared type in
  scope (the function's parameters and locals declared before the line, and the class's members
  from the file's own header: names ending in `_`);
- `sibling constant`: `Enum::a` replaced by a neighbour in its enum's declaration order, a
  `kName` by a neighbour of the same type in the file that defines it (the enums and constants
  of every product file and of the generated board headers);
- `unit scale`: a literal 1e3, 1e6, 1e9, 1e-3, 1e-6 (a unit's factor) multiplied or divided by 1000;
- `statement deleted`: an assignment, increment or reset (`x = ...;`, `++n;`, `.reset();`,
  `.clear();`, `.fill(...);`) in a function body replaced by the empty statement.

All work on one line at a time, on its code only (strings, characters and comments masked), and
are cheap: a lightweight scope model (braces: namespace, class, function) instead of a parser.
Each mutant is (1-based line, the whole replacement line, rule).
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

RULES = (
    "drop condition",
    "abs removed",
    "bound",
    "same-type variable",
    "sibling constant",
    "unit scale x1000",
    "statement deleted",
)
"""The realistic operators' names (a mutant's rule)."""
NEIGHBOURS = 2
"""How many declarations on each side of a constant or enumerator are its sibling mutants."""
SCALE_FACTORS = (1e3, 1e6, 1e9, 1e-3, 1e-6)
SCALAR = r"(?:std::)?(?:u?int(?:8|16|32|64)_t|size_t|float|double|bool|int|unsigned|long|char)"
TYPE = rf"(?:{SCALAR}|(?:\w+::)*[A-Z]\w*)"
DECLARATION = re.compile(
    rf"(?<![\w:.>])(?:const\s+|constexpr\s+|static\s+)*({TYPE})\s*&?\s+([a-z_]\w*)\s*(?=[=;,){{\[])"
)
_ENUM = re.compile(r"\benum\s+(?:class\s+|struct\s+)?(\w+)\s*(?::\s*[\w:]+\s*)?\{([^}]*)\}")
_CONSTANT = re.compile(r"\bconstexpr\s+(?:static\s+|inline\s+)*([\w:<>]+)\s+(k[A-Z]\w*)\s*[={]")
_QUALIFIED = re.compile(r"\b(\w+)::(\w+)\b")
_CONSTANT_USE = re.compile(r"(?<![\w])(k[A-Z]\w*)\b")
_ABS = re.compile(r"\b(?:std::)?(?:fabsf|fabs|abs)\s*\(")
_BOUND = re.compile(r"(?<=\s)(>=|<=|>|<)(?=\s)")
_NUMBER = re.compile(r"(?<![\w.])(\d+(?:\.\d*)?(?:[eE][+-]?\d+)?)([fFuUlL]*)(?![\w.])")
_ASSIGNMENT = re.compile(
    r"^\s*(?:(?:\+\+|--)[\w.\->\[\]]+|[\w.\->\[\]*]+(?:\+\+|--)"
    r"|[\w.\->\[\]*]+\s*(?:=(?!=)|\+=|-=|\*=|/=|\|=|&=|\^=|<<=|>>=).*"
    r"|[\w.\->\[\]]+\.(?:reset|clear|fill)\(.*\))\s*;\s*$"
)
_SELF_COMPARISON = re.compile(r"(?<![\w.>])([a-z_]\w*)\s*(?:<=|>=|==|!=|<|>)\s*\1\b(?!\s*[.(\[-])")
_KEYWORDS = {"return", "if", "for", "while", "switch", "case", "else", "do", "break", "continue"}


# --- The code of a file, masked ---------------------------------------------------------------
def code_lines(lines: Sequence[str]) -> list[str]:
    """Each line with its comments, string and character literals blanked (same length), so
    that what an operator sees is code only and positions stay those of the line."""
    result = []
    in_block = False
    for line in lines:
        out = []
        i = 0
        while i < len(line):
            c = line[i]
            if in_block:
                if line.startswith("*/", i):
                    in_block = False
                    out.append("  ")
                    i += 2
                    continue
                out.append(" " if c != "\n" else c)
            elif line.startswith("//", i):
                out.append(" " * (len(line) - i - (1 if line.endswith("\n") else 0)))
                out.append("\n" if line.endswith("\n") else "")
                break
            elif line.startswith("/*", i):
                in_block = True
                out.append("  ")
                i += 2
                continue
            elif c in "\"'" and not (c == "'" and i and line[i - 1].isalnum()):  # 1'000 separators
                end = i + 1
                while end < len(line) and line[end] != c:
                    end += 2 if line[end] == "\\" else 1
                out.append(c + " " * (min(end, len(line)) - i - 1) + (c if end < len(line) else ""))
                i = end + 1
                continue
            else:
                out.append(c)
            i += 1
        result.append("".join(out))
    return result


# --- Scopes: which lines are in which function ------------------------------------------------
@dataclass
class Function:
    """A function body: its lines (1-based, first and last) and where its signature starts."""

    signature_line: int
    first: int
    last: int


def functions_of(code: Sequence[str]) -> list[Function]:
    """The outermost function bodies of a file: a `{` outside any function whose text since the
    previous `;`, `{` or `}` ends with `)` and qualifiers, or is a constructor's initialiser
    list; namespaces, classes, enums and brace initialisers are scopes, not functions."""
    found: list[Function] = []
    stack: list[tuple[str, int, int]] = []  # kind, line of the brace, line the header started
    header: list[str] = []
    header_line = 1
    saved: list[tuple[list[str], int]] = []  # the headers around open brace initialisers
    for number, line in enumerate(code, 1):
        for c in line:
            if c == "{":
                text = " ".join("".join(header).split())
                inside = any(kind == "function" for kind, _, _ in stack)
                if inside:
                    kind = "block"
                elif re.search(r"\b(namespace|class|struct|union|enum)\b", text) or text.endswith("="):
                    kind = "scope"
                elif re.search(
                    r"\)\s*(?:const|noexcept|override|final|mutable|->\s*[\w:<>]+|\s)*$", text
                ) or (re.search(r"\)\s*:\s", text) and not re.search(r"[\w>]$", text)):
                    kind = "function"
                else:
                    kind = "init"
                stack.append((kind, number, header_line))
                if kind == "init":
                    saved.append((header, header_line))
                header, header_line = [], number
            elif c == "}":
                kind = "scope"
                if stack:
                    kind, start, started = stack.pop()
                    if kind == "function":
                        found.append(Function(started, start, number))
                if kind == "init":  # a brace initialiser: the statement or signature goes on
                    header, header_line = saved.pop() if saved else ([], number)
                    header.append("{}")
                else:
                    header, header_line = [], number
            elif c == ";":
                if not any(kind in ("function", "init") for kind, _, _ in stack) or not stack:
                    header, header_line = [], number
                else:
                    header.append(c)
            else:
                if not header and not c.isspace():
                    header_line = number
                header.append(c)
    return sorted(found, key=lambda f: f.first)


def _last_use(code: Sequence[str], function: Function, line: int, names: set[str]) -> bool:
    """Whether a parameter or local used on `line` is used on no other line of the function
    after its declaration: deleting the line would leave it unused (-Werror)."""
    for name in names:
        word = re.compile(rf"\b{re.escape(name)}\b")
        if not word.search(code[line - 1]):
            continue
        others = [n for n in range(function.signature_line, function.last + 1) if n != line]
        if sum(bool(word.search(code[n - 1])) for n in others) <= 1:
            return True
    return False


def function_at(functions: Sequence[Function], line: int) -> Function | None:
    return next((f for f in functions if f.first <= line <= f.last), None)


def declarations(code: Sequence[str], first: int, last: int) -> list[tuple[int, str, str]]:
    """(line, type, name) of the variables declared on lines first..last (1-based)."""
    found = []
    for number in range(first, last + 1):
        for match in DECLARATION.finditer(code[number - 1]):
            type_name = re.sub(r"^std::", "", match.group(1))
            if match.group(2) not in _KEYWORDS and type_name not in _KEYWORDS:
                found.append((number, type_name, match.group(2)))
    return found


# --- Sibling constants: the enums and constants of the project --------------------------------
@dataclass
class ProjectIndex:
    """The enums (name -> enumerator lists, one per definition, with the defining file) and the
    constants (per file, in declaration order with their type) that sibling mutants pick from."""

    enums: dict[str, list[tuple[str, list[str]]]] = field(default_factory=dict)
    constants: dict[str, list[tuple[str, str]]] = field(default_factory=dict)
    members: dict[str, list[tuple[str, str]]] = field(default_factory=dict)
    """A header's class members (type, name ending in `_`), for its .cpp's same-type mutants."""

    def add(self, name: str, text: str) -> None:
        code = code_lines(text.splitlines(keepends=True))
        joined = "".join(code)
        for match in _ENUM.finditer(joined):
            values = [v.split("=")[0].strip() for v in match.group(2).split(",")]
            self.enums.setdefault(match.group(1), []).append((name, [v for v in values if v]))
        for match in _CONSTANT.finditer(joined):
            self.constants.setdefault(name, []).append((match.group(1), match.group(2)))
        if name.endswith((".hpp", ".h")):
            functions = functions_of(code)
            outside = [line for number, line in enumerate(code, 1) if not _in_any(functions, number)]
            self.members[name] = [
                (t, n) for _, t, n in declarations(outside, 1, len(outside)) if n.endswith("_")
            ]

    def enum_siblings(self, enum: str, value: str, path: str) -> list[str]:
        definitions = [values for file, values in self.enums.get(enum, []) if value in values]
        own = [v for file, v in self.enums.get(enum, []) if value in v and _same_board(file, path)]
        values = (own or definitions or [[]])[0]
        return _neighbours(values, value)

    def constant_siblings(self, name: str) -> list[str]:
        for entries in self.constants.values():
            for type_name, constant in entries:
                if constant == name:
                    same = [c for t, c in entries if t == type_name]
                    return _neighbours(same, name)
        return []


def _same_board(file: str, path: str) -> bool:
    return ("head" in Path(file).parts) == ("head" in Path(path).parts)


def _in_any(functions: Sequence[Function], line: int) -> bool:
    return function_at(functions, line) is not None


def _neighbours(values: Sequence[str], value: str) -> list[str]:
    if value not in values:
        return []
    at = list(values).index(value)
    chosen = list(values[max(0, at - NEIGHBOURS) : at]) + list(values[at + 1 : at + 1 + NEIGHBOURS])
    return [v for v in chosen if v != value]


def index_of(root: Path, files: Iterable[str]) -> ProjectIndex:
    index = ProjectIndex()
    for name in files:
        index.add(name, (root / name).read_text())
    return index


# --- The operators ----------------------------------------------------------------------------
def _replace(line: str, start: int, end: int, text: str) -> str:
    return line[:start] + text + line[end:]


def drop_condition(line: str, code: str) -> list[str]:
    """Each operand of each `&&`/`||` on the line removed with its operator (an operand that
    goes on to the next or comes from the previous line is dropped only from its own side)."""
    results = []
    stripped = code.rstrip("\n")
    for match in re.finditer(r"(?<=[\s(])(&&|\|\|)(?=\s|$)", stripped):
        left = _operand_start(stripped, match.start())
        right = _operand_end(stripped, match.end())
        if left is not None and stripped[left : match.start()].strip():
            results.append(_tidy(_replace(line, left, match.end(), "")))
        if right is not None and stripped[match.end() : right].strip():
            results.append(_tidy(_replace(line, match.start(), right, "")))
    return results


def _tidy(line: str) -> str:
    indent = line[: len(line) - len(line.lstrip())]
    body = re.sub(r"[ \t]+([);])", r"\1", re.sub(r"\([ \t]+", "(", line.lstrip()))
    return indent + re.sub(r"[ \t]{2,}", " ", body)


def _operand_start(code: str, op: int) -> int | None:
    """Where the operand before the operator at `op` starts, or None if the line has not all of it."""
    depth = 0
    for i in range(op - 1, -1, -1):
        c = code[i]
        if c in ")]":
            depth += 1
        elif c in "([":
            if depth == 0:
                return i + 1
            depth -= 1
        elif depth == 0 and (
            c in ",;?{"
            or (c == "=" and code[i - 1 : i] not in ("=", "!", "<", ">") and code[i + 1 : i + 2] != "=")
            or code[max(0, i - 1) : i + 1] in ("&&", "||")
            or (re.search(r"\breturn$", code[: i + 1]) and not code[i + 1 : i + 2].isalnum())
        ):
            return i + 1
    return None if code[:op].strip() == "" else len(code) - len(code.lstrip())


def _operand_end(code: str, op: int) -> int | None:
    """Where the operand after the operator ending at `op` ends (before the next operator or
    the closing bracket), or None if it goes on to the next line."""
    depth = 0
    i = op
    while i < len(code):
        c = code[i]
        if c in "([":
            depth += 1
        elif c in ")]":
            if depth == 0:
                return _before_space(code, i)
            depth -= 1
        elif depth == 0 and (
            code.startswith(("&&", "||"), i)
            or c in ",;?{"
            or (c == ":" and ":" not in code[i - 1 : i + 2 : 2])
        ):
            return _before_space(code, i)
        i += 1
    return None


def _before_space(code: str, i: int) -> int:
    while i > 0 and code[i - 1].isspace():
        i -= 1
    return i


def abs_removed(line: str, code: str) -> list[str]:
    return [_replace(line, m.start(), m.end(), "(") for m in _ABS.finditer(code)]


def bound(line: str, code: str) -> list[str]:
    swap = {">=": ">", ">": ">=", "<=": "<", "<": "<="}
    if re.search(r"\btemplate\b|#", code):
        return []
    return [_replace(line, m.start(), m.end(), swap[m.group(1)]) for m in _BOUND.finditer(code)]


def unit_scale(line: str, code: str) -> list[str]:
    results = []
    for match in _NUMBER.finditer(code):
        digits, suffix = match.group(1), match.group(2)
        value = float(digits)
        if not any(abs(value - f) <= 1e-12 * f for f in SCALE_FACTORS):
            continue
        integral = "." not in digits and "e" not in digits.lower()
        for scaled in (value * 1000, value / 1000):
            if integral:
                if scaled < 1 or scaled != int(scaled) or scaled > 1e9:
                    continue
                text = str(int(scaled))
            else:
                text = f"{scaled:g}"
                if not re.search(r"[.e]", text):
                    text += ".0"
            results.append(_replace(line, match.start(), match.end(), text + suffix))
    return results


def statement_deleted(line: str, code: str) -> list[str]:
    stripped = code.rstrip("\n")
    if not _ASSIGNMENT.match(stripped) or stripped.count("(") != stripped.count(")"):
        return []
    if stripped.split()[0] in _KEYWORDS:
        return []
    indent = line[: len(line) - len(line.lstrip())]
    return [indent + ";" + ("\n" if line.endswith("\n") else "")]


def same_type_variable(line: str, code: str, candidates: dict[str, list[str]]) -> list[str]:
    """`candidates`: name -> the other names of its type in scope."""
    results = []
    declared_here = {name for _, _, name in declarations([code], 1, 1)}
    for match in re.finditer(r"(?<![\w.>:])([a-z_]\w*)\b(?!\s*\()", code):
        name = match.group(1)
        if name in declared_here or name not in candidates:
            continue
        before = code[: match.start()].rstrip()
        if before.endswith(("->", ".", "::")):
            continue
        for other in candidates[name]:
            mutant = _replace(line, match.start(), match.end(), other)
            if not _SELF_COMPARISON.search(mutant):  # x < x: -Werror=tautological-compare
                results.append(mutant)
    return results


def sibling_constant(line: str, code: str, index: ProjectIndex, path: str) -> list[str]:
    results = []
    if _CONSTANT.search(code) or re.search(r"\benum\b|^\s*case\b", code):  # a case label: duplicated
        return []
    for match in _QUALIFIED.finditer(code):
        for other in index.enum_siblings(match.group(1), match.group(2), path):
            results.append(_replace(line, match.start(2), match.end(2), other))
    for match in _CONSTANT_USE.finditer(code):
        for other in index.constant_siblings(match.group(1)):
            results.append(_replace(line, match.start(1), match.end(1), other))
    return results


# --- A file's realistic mutants ---------------------------------------------------------------
def realistic_mutants(
    text: str, path: str, index: ProjectIndex | None = None, members: Sequence[tuple[str, str]] = ()
) -> list[tuple[int, str, str]]:
    """Every realistic mutant of a file: (1-based line, replacement line, rule), line order."""
    index = index or ProjectIndex()
    lines = text.splitlines(keepends=True)
    code = code_lines(lines)
    functions = functions_of(code)
    found: list[tuple[int, str, str]] = []
    for number, (line, masked) in enumerate(zip(lines, code, strict=True), 1):
        if not masked.strip() or masked.lstrip().startswith("#") or "static_assert" in masked:
            continue
        function = function_at(functions, number)
        mutants: list[tuple[str, str]] = []
        mutants += [(m, "drop condition") for m in drop_condition(line, masked)]
        mutants += [(m, "abs removed") for m in abs_removed(line, masked)]
        mutants += [(m, "bound") for m in bound(line, masked)]
        mutants += [(m, "unit scale x1000") for m in unit_scale(line, masked)]
        mutants += [(m, "sibling constant") for m in sibling_constant(line, masked, index, path)]
        if function is not None and function.first < number:
            scope = declarations(code, function.signature_line, number - 1)
            if not _last_use(code, function, number, {name for _, _, name in scope}):
                mutants += [(m, "statement deleted") for m in statement_deleted(line, masked)]
            by_type: dict[str, list[str]] = {}
            for _, type_name, name in scope:
                by_type.setdefault(type_name, [])
                if name not in by_type[type_name]:
                    by_type[type_name].append(name)
            for type_name, name in members:
                by_type.setdefault(type_name, [])
                if name not in by_type[type_name]:
                    by_type[type_name].append(name)
            candidates = {
                name: [other for other in names if other != name]
                for names in by_type.values()
                for name in names
                if len(names) > 1
            }
            mutants += [(m, "same-type variable") for m in same_type_variable(line, masked, candidates)]
        seen = {line}
        for replacement, rule in mutants:
            if replacement not in seen:
                seen.add(replacement)
                found.append((number, replacement, rule))
    return found
