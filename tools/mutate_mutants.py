"""The firmware's mutants: which files are product code, every mutant of a file (universalmutator's
C++ rules and the realistic operators of mutate_operators), their stable ids, the reviewed
equivalents, and the stratified sample `make mutate` runs (mutate_sampling)."""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import re
import subprocess
import tomllib
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from fnmatch import fnmatch
from pathlib import Path

import mutate_operators as operators

REPO = Path(__file__).resolve().parent.parent
PRODUCT = ("firmware/**/*.cpp", "firmware/**/*.hpp")
NOT_PRODUCT = (
    "*Test.cpp",
    "*TestSupport.*",
    "firmware/bench/*",
    "firmware/canopen/fuzz/*",
    "firmware/joint/testing/*",
    "firmware/canopen/MemoryPort.hpp",  # the engine's tests' CanPort double
    "firmware/canopen/BlockCrcReference.hpp",  # the tests' reference CRC
    "firmware/platform/linux/ParameterStoreCrash*",  # the crash test's child process
    "firmware/core/PortableCheck.cpp",  # a compile-only check
    # The Cortex-M platform, and the node's views of the joint only it uses so far: built and
    # tested by the cross build (make cortex-m), not the host build a mutant is tested in.
    "firmware/platform/cortex-m/*",
    "firmware/platform/common/*",
)
RULES = ("universal.rules", "cpp.rules", "c_like.rules")
"""universalmutator's rule files for C++, as its own `mutate FILE cpp` picks them."""
NOT_MUTATED = (
    r"^\s*#",  # preprocessor: includes, guards
    r"^\s*//",  # comments
    r"static_assert",  # compile-time checks: a mutant either does not build or changes nothing
    r"\bassert\s*\(",  # NDEBUG in the release-like test build
)
EQUIVALENTS = REPO / "tools" / "mutants-equivalent.toml"
GENERATED_HEADERS = ("build/protocol/include/board/*.hpp", "build/protocol/head/include/board/*.hpp")
"""The board tables' generated headers (`make build`): their enums (FieldId...) are siblings too."""


@dataclass(frozen=True)
class Mutant:
    id: str
    path: str  # relative to the source root
    line: int  # 1-based
    original: str
    replacement: str
    rule: str

    def apply(self, text: str) -> str:
        lines = text.splitlines(keepends=True)
        if lines[self.line - 1] != self.original:
            raise ValueError(f"{self.path}:{self.line} is no longer {self.original!r}")
        lines[self.line - 1] = self.replacement
        return "".join(lines)


# --- Which mutants ---------------------------------------------------------------------------
def product_files(
    root: Path, product: Sequence[str] = PRODUCT, not_product: Sequence[str] = NOT_PRODUCT
) -> list[str]:
    found = {str(p.relative_to(root)) for pattern in product for p in root.glob(pattern) if p.is_file()}
    return sorted(
        f
        for f in found
        if not any(fnmatch(f, pattern) or fnmatch(Path(f).name, pattern) for pattern in not_product)
    )


def source_digest(root: Path, path: str) -> str:
    """The SHA-1 of a product file (`path` relative to `root`): a mutant's result holds while it
    is the same."""
    return hashlib.sha1((root / path).read_bytes()).hexdigest()


def ninja_deps(build: Path, check: bool = False) -> dict[str, list[Path]]:
    """ninja's deps log of `build`: each output it recorded (relative to the build, e.g. an object
    file) and the files it was compiled from, resolved, in the log's order. `check`: a failing
    ninja raises; else the log reads as empty."""
    log = subprocess.run(
        ["ninja", "-C", str(build), "-t", "deps"], capture_output=True, text=True, check=check
    )
    deps: dict[str, list[Path]] = {}
    current: list[Path] | None = None
    for line in log.stdout.splitlines():
        if line and not line.startswith(" "):
            current = deps.setdefault(line.split(":")[0], [])
        elif current is not None and line.strip():
            current.append((build / line.strip()).resolve())
    return deps


def compiled_by(build: Path, source: Path) -> set[str]:
    """The files of `source` (paths relative to it) that the built tree `build` compiles: its
    translation units (compile_commands.json) and the headers they include (ninja's deps log).
    A product file outside this set (another target's platform, e.g. the bare-metal qemu-virt
    firmware) is never built by the host build a mutant is tested in, so its mutants would
    "survive" every test unmutated: the sample leaves such files out and the report says so."""
    commands_path = build / "compile_commands.json"
    if not commands_path.exists() or not (build / ".ninja_deps").exists():
        raise ValueError(
            f"no built host tree at {build} (run `make build` first): the sample draws only "
            "the product files the host build compiles"
        )
    found = {Path(e["directory"], e["file"]).resolve() for e in json.loads(commands_path.read_text())}
    found |= {path for paths in ninja_deps(build, check=True).values() for path in paths}
    source = source.resolve()
    return {str(p.relative_to(source)) for p in found if p.is_relative_to(source)}


def mutants_of(
    root: Path,
    path: str,
    index: operators.ProjectIndex | None = None,
    *,
    realistic: bool = True,
    filtered: bool = True,
) -> list[Mutant]:
    """Every mutant of one file, in line order: universalmutator's C++ rules and, with
    `realistic`, mutate_operators' (siblings from `index`); `filtered` drops those that cannot
    compile or change nothing (`plausible`). The id is made of the file, the line's text, the
    replacement and which such occurrence it is: it survives edits elsewhere in the file (the
    equivalents list names mutants by it)."""
    from universalmutator import mutator

    text = (root / path).read_text()
    source = text.splitlines(keepends=True)
    with contextlib.redirect_stdout(io.StringIO()):  # it prints its progress
        found = mutator.mutants_regexp(
            source, ruleFiles=list(RULES), ignorePatterns=list(NOT_MUTATED), ignoreStringOnly=True
        )
    candidates = [
        (line, replacement, rule_used[0].strip() if isinstance(rule_used, tuple) else str(rule_used))
        for line, replacement, rule_used, _ in found
    ]
    if realistic:
        members = (index.members.get(str(Path(path).with_suffix(".hpp")), []) if index else []) or []
        candidates += operators.realistic_mutants(text, path, index, members)
    code = operators.code_lines(source) if filtered else []
    functions = operators.functions_of(code) if filtered else []
    seen: Counter[tuple[str, str]] = Counter()
    taken: set[tuple[int, str]] = set()
    result = []
    for line, replacement, rule in sorted(candidates, key=lambda m: (m[0], m[1])):
        original = source[line - 1]
        if (line, replacement) in taken:
            continue  # the same change by two rules: one mutant
        taken.add((line, replacement))
        if filtered and not plausible(code, functions, line, original, replacement, rule):
            continue
        seen[(original, replacement)] += 1
        key = f"{path}\0{original}\0{replacement}\0{seen[(original, replacement)]}"
        digest = hashlib.sha1(key.encode()).hexdigest()[:8]
        result.append(Mutant(f"{Path(path).stem}-{digest}", path, line, original, replacement, rule))
    return result


NEVER_COMPILES = frozenset({"back_inserter ==> front_inserter"})
"""universalmutator's rules whose mutants never compile here (no container has push_front)."""
_SWAP_RULE = r"([,\(\[\{])([^=,\)\}\]]+),"
_PARAMETER = re.compile(r"[\w>*&]\s+[a-z_]\w*\s*[,)]")
"""A parameter's declaration (`Type name,`): swapping two of them changes the signature."""
BINARY_OPERATORS = frozenset(
    {"<", ">", "<=", ">=", "==", "!=", "&", "|", "&&", "||", "<<", ">>", "*", "/", "%", "+", "-", "^"}
    | {"=", "+=", "-=", "*=", "/=", "|=", "&=", "^=", "<<=", ">>="}
)


def _operator_at(line: str, at: int) -> str:
    """The run of operator characters around `at`."""
    start, end = at, at
    while start and line[start - 1] in "<>&*|=!+-/%^":
        start -= 1
    while end < len(line) and line[end] in "<>&*|=!+-/%^":
        end += 1
    return line[start:end]


def _common(a: str, b: str) -> int:
    """The length of the characters a and b start with in common."""
    return next((i for i, (x, y) in enumerate(zip(a, b, strict=False)) if x != y), min(len(a), len(b)))


def _renames_part_of_a_name(original: str, replacement: str) -> bool:
    """Whether the change is letters inside an identifier (a word rule matched part of one)."""
    prefix = _common(original, replacement)
    suffix = _common(original[prefix:][::-1], replacement[prefix:][::-1])
    changed = original[prefix : len(original) - suffix]
    if not changed.isalpha():
        return False
    before = original[prefix - 1 : prefix]
    after = original[len(original) - suffix : len(original) - suffix + 1]
    return (before.isalnum() or before == "_") or (after.isalnum() or after == "_")


def _after_condition(line: str) -> str:
    """What follows the parenthesised condition of a line's `if (` or `while (`."""
    match = re.search(r"\b(?:if|while)\s*\(", line)
    if match is None:
        return ""
    depth = 0
    for i in range(match.end() - 1, len(line)):
        depth += {"(": 1, ")": -1}.get(line[i], 0)
        if depth == 0:
            return line[i + 1 :]
    return ""


def _in_loop(code: Sequence[str], function: operators.Function | None, line: int, switch_too: bool) -> bool:
    """Whether a line sits in a loop (or a switch) of its function, by indentation: one of the
    lines that open its enclosing blocks starts with for, while or do (or switch)."""
    if function is None:
        return False
    keywords = ("for", "while", "do") + (("switch",) if switch_too else ())
    indent = len(code[line - 1]) - len(code[line - 1].lstrip())
    for number in range(line - 1, function.first - 1, -1):
        text = code[number - 1]
        if not text.strip():
            continue
        depth = len(text) - len(text.lstrip())
        if depth < indent:
            indent = depth
            if re.match(rf"\s*(?:\}}\s*)?(?:{'|'.join(keywords)})\b", text):
                return True
    return False


def _spaced(line: str, at: int) -> bool:
    """Whether the operator at `at` has spaces on both sides (a binary operator)."""
    start, end = at, at + 1
    while start and line[start - 1] in "<>&*|=!":
        start -= 1
    while end < len(line) and line[end] in "<>&*|=":
        end += 1
    return line[start - 1 : start].isspace() and line[end : end + 1].isspace()


_COMMENT_OUT = re.compile(r"^\s*/\*.*\*/\s*$")
_ACCESS = re.compile(r"^\s*(public|private|protected)\s*:\s*$")


def plausible(
    code: Sequence[str],
    functions: Sequence[operators.Function],
    line: int,
    original: str,
    replacement: str,
    rule: str = "",
) -> bool:
    """Whether a mutant may compile and change something, by cheap checks of its line: not a
    change behind a // comment, not digits inside a name or a hex or float literal, brackets
    as balanced as before, no operator swapped for a template's angle bracket, a reference's or
    pointer's `&` or `*` (unspaced: a binary operator has spaces around it here); a statement
    added (break, continue) or a line commented out only in a function's body, and commented
    out only if it is a whole statement that is neither a declaration (its variable is used
    further on) nor the last return of its function (-Werror=return-type)."""
    if code_of(original) == code_of(replacement):
        return False  # a statement appended behind a // comment: no change at all
    if changes_digits_of_a_name(original, replacement):
        return False  # uint32_t -> uint(32+1)_t, 0x3F -> (0+1)x3F: never compiles
    before, after = code_of(original), code_of(replacement)
    if not _COMMENT_OUT.match(replacement) and any(
        before.count(a) - before.count(b) != after.count(a) - after.count(b) for a, b in ("()", "[]", "{}")
    ):
        return False
    start = next((i for i, (a, b) in enumerate(zip(original, replacement, strict=False)) if a != b), None)
    while start and original[start - 1] in "<>&*|=!" and original[start : start + 1] not in "<>&*|":
        start -= 1
    if start is not None and original[start : start + 1] in set("<>&*|+-/%^"):
        token, spaced = _operator_at(original, start), _spaced(original, start)
        if spaced and _operator_at(replacement, start) not in BINARY_OPERATORS:
            return False  # a binary operator removed or made into none
        if not spaced and original[start] in "<>&*|" and token not in ("->",):
            return False  # a template's bracket, a reference, a pointer
        if token in ("++", "--") and _operator_at(replacement, start) not in ("++", "--"):
            return False
        if spaced and '"' in before and original[start] in "+-":
            return False  # a string's concatenation
    if rule not in operators.RULES and _renames_part_of_a_name(original, replacement):
        return False  # end -> begin inside VendorId
    if rule.startswith(("if", "while")) and not replacement.rstrip().endswith(
        _after_condition(original).rstrip()
    ):
        return False  # the rule's greedy (.*) took the statement after the condition too
    if rule in NEVER_COMPILES or (rule.startswith(_SWAP_RULE) and _PARAMETER.search(original)):
        return False
    function = operators.function_at(functions, line)
    in_body = function is not None and function.first < line < function.last
    added = replacement[len(original) :].strip() if replacement.startswith(original) else ""
    if added in ("break;", "continue;") and not (
        in_body and _in_loop(code, function, line, added == "break;")
    ):
        return False  # break or continue outside a loop (or a switch)
    if replacement.count("\n") > original.count("\n") and not in_body:
        return False
    if _COMMENT_OUT.match(replacement):
        if not in_body:
            return False
        masked = code[line - 1].strip()
        previous = next((c.strip() for c in reversed(code[: line - 1]) if c.strip()), "{")
        following = next((c.strip() for c in code[line:] if c.strip()), "}")
        if not masked.endswith(";") or any(masked.count(a) != masked.count(b) for a, b in ("()", "{}")):
            return False  # part of a statement
        if not previous.endswith((";", "{", "}", ":")) or previous.startswith("#"):
            return False  # a statement's continuation
        if _ACCESS.match(masked) or operators.DECLARATION.match(masked):
            return False
        if masked.startswith("return ") and following.startswith("}"):
            return False
    return True


_INTEGER_LITERAL = re.compile(r"(?<![\w.'])\d+(?:[uU]?[lL]{0,2}|[lL]{1,2}[uU]?)(?![\w.'])")


def changes_digits_of_a_name(original: str, replacement: str) -> bool:
    """Whether the first change is to digits that are not a whole integer literal: part of a
    name (uint32_t), of a hex or float literal (0x3F, 1.0F). universalmutator's literal rule
    matches those too, and such a mutant never compiles: not generated, so as not to spend a
    build on it."""
    start = next((i for i, (a, b) in enumerate(zip(original, replacement, strict=False)) if a != b), None)
    if start is None or not (original[start].isdigit() or (start and original[start - 1].isdigit())):
        return False
    while start and original[start - 1].isdigit():
        start -= 1
    return _INTEGER_LITERAL.match(original, start) is None


def code_of(line: str) -> str:
    """A line's code without its // comment, whitespace normalised."""
    return " ".join(line.split("//", 1)[0].split())


def project_index(root: Path, files: Iterable[str]) -> operators.ProjectIndex:
    """The enums, constants and members of the product files and of the generated headers."""
    files = list(files)
    index = operators.index_of(root, files)
    for pattern in GENERATED_HEADERS:
        for header in sorted(REPO.glob(pattern)):
            index.add(str(header.relative_to(REPO)), header.read_text())
    return index


def all_mutants(root: Path, files: Iterable[str], **options: bool) -> list[Mutant]:
    files = list(files)
    index = project_index(root, files)
    return [m for path in files for m in mutants_of(root, path, index, **options)]


def load_equivalents(path: Path = EQUIVALENTS) -> dict[str, str]:
    """Reviewed equivalent mutants: id -> reason."""
    if not path.exists():
        return {}
    entries = tomllib.loads(path.read_text()).get("equivalent", [])
    return {entry["id"]: entry["reason"] for entry in entries}
