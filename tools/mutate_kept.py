"""Verdicts of `make mutate` kept in the repository (tools/mutants-judged.json), so that a run of
several hundred mutants can span machines and sessions: a fresh checkout has no build/mutate, and
each mutant's verdict costs a build, its unit tests and its scenarios.

`tools/mutate.py keep` adds a run's finished verdicts to the file; `tools/mutate.py run` starts
each mutant whose file is unchanged (the same SHA-1 as when it was judged) from its kept verdict
instead of judging it again. A kept verdict names the commit it was judged at; a survivor is only
ever judged against the tests of then, so after adding a test that should kill it, judge it again
with `run --mutant ID --again` and keep it again.
"""

from __future__ import annotations

import json
import subprocess
from collections.abc import Iterable
from pathlib import Path

from mutate_mutants import REPO, source_digest
from mutation_report import write_json

KEPT = REPO / "tools" / "mutants-judged.json"
FORMAT = 1


def head_commit(repo: Path = REPO) -> str:
    """The checkout's commit (with "+changes" when its tracked files differ from it)."""
    commit = subprocess.run(
        ["git", "rev-parse", "HEAD"], cwd=repo, capture_output=True, text=True, check=False
    ).stdout.strip()
    if not commit:
        return "unknown"
    dirty = subprocess.run(
        ["git", "diff", "--quiet", "HEAD", "--"], cwd=repo, capture_output=True, check=False
    ).returncode
    return commit + ("+changes" if dirty else "")


def load(path: Path = KEPT) -> dict[str, dict]:
    """The kept verdicts by mutant id (none when the file is absent)."""
    if not path.exists():
        return {}
    data = json.loads(path.read_text())
    if data.get("format") != FORMAT:
        raise ValueError(f"{path}: format {data.get('format')!r}, this tool reads {FORMAT}")
    return data["mutants"]


def finished(result: dict) -> bool:
    """Whether a mutant's result is a whole verdict: it did not compile, or its scenarios judged it
    (a result still waiting for its scenarios, or whose scenarios were not run, is not kept)."""
    if not result.get("compiled", False):
        return "compiled" in result
    return result.get("scenarios") is not None and result.get("approved") is not None


def compact(result: dict, commit: str) -> dict:
    """What is kept of a result: the unit tests it selected as a count, the commit it was judged at."""
    kept = {**result, "judged_at": result.get("judged_at", commit)}
    unit = kept.get("unit")
    if unit and isinstance(unit.get("selected"), list):
        kept["unit"] = {**unit, "selected": len(unit["selected"])}
    return kept


def keep(out: Path, path: Path = KEPT, commit: str | None = None) -> tuple[int, int]:
    """Add every finished verdict under `out`/mutants to `path` (a newer verdict of the same
    mutant replaces the kept one): (added or replaced, kept in all)."""
    commit = commit or head_commit()
    kept = load(path)
    changed = 0
    for result_path in sorted((out / "mutants").glob("*/result.json")):
        result = json.loads(result_path.read_text())
        if not finished(result):
            continue
        entry = compact(result, commit)
        before = kept.get(entry["id"])
        same = before is not None and {**before, "judged_at": None} == {**entry, "judged_at": None}
        if not same:  # a verdict kept again without its commit keeps the first commit named
            kept[entry["id"]] = entry
            changed += 1
    write_json(path, {"format": FORMAT, "mutants": dict(sorted(kept.items()))})
    return changed, len(kept)


def seed(out: Path, source_root: Path, ids: Iterable[str], path: Path = KEPT) -> int:
    """Start each of `ids` that has no result under `out` from its kept verdict, when its file is
    the one it was judged on: the number seeded."""
    kept = load(path)
    digests: dict[str, str | None] = {}
    seeded = 0
    for mutant_id in ids:
        entry = kept.get(mutant_id)
        result_path = out / "mutants" / mutant_id / "result.json"
        if entry is None or result_path.exists():
            continue
        if entry["path"] not in digests:
            exists = (source_root / entry["path"]).exists()
            digests[entry["path"]] = source_digest(source_root, entry["path"]) if exists else None
        if digests[entry["path"]] != entry.get("source_sha1"):
            continue  # its file changed since: judged again
        write_json(result_path, entry)
        seeded += 1
    return seeded
