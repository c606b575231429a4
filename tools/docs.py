"""The manual: build it from docs/ with MkDocs, and keep the command outputs it shows true.

A block of a page that shows what a command prints is marked by the command, so it is produced by
running it rather than copied by hand:

    <!-- output of: hilrig new-board --help -->
    ```text
    ...
    ```

`check` runs each marked command (in the checkout, `.venv/bin` first on PATH, 100 columns) and
fails, with the difference, where a page shows something else; `update` writes what the commands
print into the pages; `build` checks, then builds the site into build/site with MkDocs in strict
mode (a broken link or anchor fails it). `make docs` runs `build`, and so does `make test`.

    python tools/docs.py check | update | build
"""

from __future__ import annotations

import argparse
import difflib
import os
import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
PAGES = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
BLOCK = re.compile(r"(<!-- output of: (?P<command>[^\n]*?) -->\n```text\n)(?P<shown>.*?)(```)", re.S)
COMMAND_TIMEOUT_S = 120


def command_output(command: str) -> str:
    env = dict(os.environ, COLUMNS="100", PATH=f"{REPO / '.venv' / 'bin'}{os.pathsep}{os.environ['PATH']}")
    done = subprocess.run(
        command, shell=True, cwd=REPO, env=env, capture_output=True, text=True, timeout=COMMAND_TIMEOUT_S
    )
    if done.returncode != 0:
        raise SystemExit(f"docs: `{command}` failed (exit {done.returncode}): {done.stderr.strip()[-400:]}")
    return done.stdout if done.stdout.endswith("\n") else done.stdout + "\n"


def rewritten(page: Path) -> tuple[str, list[str]]:
    """The page with every marked block as its command prints it, and the commands that differed."""
    text = page.read_text()
    differed: list[str] = []

    def fill(match: re.Match[str]) -> str:
        output = command_output(match["command"])
        if output != match["shown"]:
            differed.append(match["command"])
            diff = difflib.unified_diff(
                match["shown"].splitlines(), output.splitlines(), "shown", "printed", lineterm="", n=1
            )
            print(f"{page.relative_to(REPO)}: `{match['command']}` prints otherwise:", *diff, sep="\n")
        return match[1] + output + match[4]

    return BLOCK.sub(fill, text), differed


def broken_readme_links() -> list[str]:
    """The README's relative links whose file does not exist (MkDocs checks the docs' own)."""
    readme = REPO / "README.md"
    targets = re.findall(r"\]\(([^)#:]+)(?:#[^)]*)?\)", readme.read_text())
    return [target for target in targets if not (REPO / target).exists()]


def check(update: bool) -> int:
    stale = 0
    for target in broken_readme_links():
        print(f"docs: README.md links to {target}, which does not exist")
        stale += 1
    for page in PAGES:
        text, differed = rewritten(page)
        if differed and update:
            temporary = page.with_name(f".{page.name}.tmp")
            temporary.write_text(text)
            temporary.replace(page)
            print(f"docs: updated {page.relative_to(REPO)} ({len(differed)} blocks)")
        elif differed:
            stale += len(differed)
    if stale:
        print(f"docs: {stale} problems; a block that shows stale output: `python tools/docs.py update`")
        return 1
    return 0


def build() -> int:
    if check(update=False) != 0:
        return 1
    mkdocs = REPO / ".venv" / "bin" / "mkdocs"
    done = subprocess.run([str(mkdocs), "build", "--strict", "--quiet"], cwd=REPO, check=False)
    if done.returncode != 0:
        print("docs: mkdocs build --strict failed: a broken link, anchor or nav entry (above)")
        return 1
    print(f"docs: the site is in {REPO / 'build' / 'site'} (open index.html)")
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("action", choices=["check", "update", "build"])
    action = parser.parse_args().action
    try:
        return build() if action == "build" else check(update=action == "update")
    except KeyboardInterrupt:
        print("docs: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
