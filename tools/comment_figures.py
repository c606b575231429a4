"""Find comments that carry measurements or this project's issue numbers.

A comment says what the code does and why. A figure measured on some day ("N cycles took T
seconds", "this many cycles per second against that many") goes stale the day the code or the
machine changes, and nothing checks it: figures live in `make bench`, which measures them again,
and in commit messages, which are dated. An issue number says where a change came from, which is
the commit's business too.

    python tools/comment_figures.py            # lists findings, exit 1 if any
    python tools/comment_figures.py rig/x.py   # only these files (or directories)

What counts, in the comments and docstrings of the Python, C and C++ of firmware/, protocol/,
rig/, dashboards/ and tools/ (tests too: a test's comment ages like any other):
- "issue" and a number (this project's issues; another project's are cited by "#" and number);
- within one sentence of a comment (a run of comment lines, a docstring), a time or a rate (`8.5 s`, `20 us`,
  in cycles/s or KiB/s, a factor with "x") together with a word that says it was measured (took,
  measured, ran at, costs, faster, slower), unless the sentence states a goal or a bound (goal,
  at least, at most, budget, floor, guard, timeout, bound): that is what the code asks, not what
  a machine did.
"""

from __future__ import annotations

import ast
import io
import re
import sys
import tokenize
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
SCANNED_DIRECTORIES = ("firmware", "protocol", "rig", "dashboards", "tools", "tests")
PYTHON_SUFFIXES = (".py",)
C_SUFFIXES = (".c", ".h", ".cpp", ".hpp")
ISSUE = re.compile(r"\bissues? \d+\b", re.IGNORECASE)
FIGURE = re.compile(
    r"\b\d+(?:[.,]\d+)?(?:\s?-\s?\d+(?:\.\d+)?)?\s?"
    r"(?:ms|us|µs|ns|s|min|cycles/s|frames/s|[kKMG]i?B/s|x|×)(?![\w/])"
)
MEASURED = re.compile(r"\b(?:took|measured|ran at|runs at|costs?|faster|slower)\b", re.IGNORECASE)
# A goal or a bound the code sets says so: "at least 3x faster" is what a benchmark asks.
GOAL = re.compile(r"\b(?:goal|at least|at most|budget|floor|guard|timeout|bound)\b", re.IGNORECASE)


@dataclass(frozen=True)
class Finding:
    path: Path
    line: int
    what: str

    def __str__(self) -> str:
        return f"{self.path.relative_to(REPO)}:{self.line}: {self.what}"


SENTENCE_END = re.compile(r"(?<=[.;!?])\s+|\s+\(|\)\s+")


def _judge(path: Path, line: int, text: str) -> Iterator[Finding]:
    issue = ISSUE.search(text)
    if issue:
        yield Finding(
            path, line, f"an issue number in a comment ({issue.group(0)!r}): it belongs in the commit message"
        )
    for sentence in SENTENCE_END.split(text):
        figure = FIGURE.search(sentence)
        measured = MEASURED.search(sentence)
        if figure and measured and not GOAL.search(sentence):
            yield Finding(
                path,
                line,
                f"a measurement in a comment ({figure.group(0)!r}, {measured.group(0)!r}): "
                "figures go in `make bench` and commit messages",
            )
            return


def python_comments(source: str) -> Iterator[tuple[int, str]]:
    """(first line, text) of each run of comment lines and of each docstring."""
    run: list[str] = []
    run_start = 0
    last_line = -2
    try:
        for token in tokenize.generate_tokens(io.StringIO(source).readline):
            if token.type != tokenize.COMMENT:
                continue
            line = token.start[0]
            if line != last_line + 1 and run:
                yield run_start, " ".join(run)
                run = []
            if not run:
                run_start = line
            run.append(token.string.lstrip("#").strip())
            last_line = line
    except (tokenize.TokenError, SyntaxError):
        return
    if run:
        yield run_start, " ".join(run)
    # Docstrings, and the strings that document an attribute or a constant below its assignment.
    for node in ast.walk(ast.parse(source)):
        if (
            isinstance(node, ast.Expr)
            and isinstance(node.value, ast.Constant)
            and isinstance(node.value.value, str)
        ):
            yield node.lineno, " ".join(node.value.value.split())


C_COMMENT = re.compile(r"/\*.*?\*/|//[^\n]*|\"(?:\\.|[^\"\\\n])*\"|'(?:\\.|[^'\\\n])*'", re.S)


def c_comments(source: str) -> Iterator[tuple[int, str]]:
    """(first line, text) of each /* */ comment and each run of // lines."""
    run: list[str] = []
    run_start = 0
    last_line = -2
    for match in C_COMMENT.finditer(source):
        text = match.group(0)
        line = source.count("\n", 0, match.start()) + 1
        if text.startswith("/*"):
            yield line, " ".join(text[2:-2].replace("*", " ").split())
        elif text.startswith("//"):
            if line != last_line + 1 and run:
                yield run_start, " ".join(run)
                run = []
            if not run:
                run_start = line
            run.append(text[2:].strip())
            last_line = line
    if run:
        yield run_start, " ".join(run)


def scan_file(path: Path) -> list[Finding]:
    source = path.read_text(errors="replace")
    comments = python_comments(source) if path.suffix in PYTHON_SUFFIXES else c_comments(source)
    return [finding for line, text in comments for finding in _judge(path, line, text)]


def scanned_files(root: Path = REPO) -> list[Path]:
    files: list[Path] = []
    for directory in SCANNED_DIRECTORIES:
        for path in sorted((root / directory).rglob("*")):
            if (
                path.suffix in PYTHON_SUFFIXES + C_SUFFIXES
                and path.is_file()
                and "__pycache__" not in path.parts
            ):
                files.append(path)
    return files


def scan(paths: Iterable[Path]) -> list[Finding]:
    return [finding for path in paths for finding in scan_file(path)]


def main(argv: list[str]) -> int:
    if argv:
        paths: list[Path] = []
        for argument in argv:
            given = Path(argument).resolve()
            if not given.exists():
                print(f"comment_figures: no such file or directory: {argument}", file=sys.stderr)
                return 2
            paths += (
                [p for p in sorted(given.rglob("*")) if p.suffix in PYTHON_SUFFIXES + C_SUFFIXES]
                if given.is_dir()
                else [given]
            )
    else:
        paths = scanned_files()
    findings = scan(paths)
    for finding in findings:
        print(finding)
    if findings:
        print(
            f"comment_figures: {len(findings)} comments to reword (what and why, no figures or issue numbers)"
        )
    return 1 if findings else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
