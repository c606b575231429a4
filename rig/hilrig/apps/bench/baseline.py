"""`make bench`'s baseline: the Rig's lockstep cycle and the engine's exchange alone of another
commit (its own `tools/rig_probe.py rig` and `engine`), counted under callgrind beside the
checkout's in the same run, with the same Python and the same lengths, and judged: the checkout's
instructions per cycle within 10 % of the baseline's (new/old <= 1.1).

`BASELINE=<commit>` (`make bench`, `make bench-baseline`) picks the commit; without it the
baseline is DEFAULT_BASELINE, the last commit before the rig's folders became its layers (wire/,
engine/, session/, observe/, apps/, cli/), so the report always holds that comparison.

The baseline's tree is exported with `git archive` into <bench folder>/baseline/<commit>/ (not
with `git worktree add`, which would register it in the repository's .git, shared with every
other worktree of it) and made runnable there as a checkout is, each step by the tree's own
code: its C extensions (the raw-socket exchange, the plant) built in place by its `rig/setup.py`
with the bench's Python, and the EDS its fake node loads generated into its build/protocol/ by
its `boardproto`, the command its CMake runs. A marker written last says the tree is whole; the
next run reuses it. An export of another commit, or one left half-done, is removed when a run
prepares its own; `tools/bench.py baseline --remove` removes them all, and `make clean` with
build/.

Before anything is counted, each tree's probe runs a few cycles natively (`check_probe`): that
proves the probe imports the rig and boardproto from its own tree (the venv's editable install
maps them to the checkout), and it compiles the tree's .pyc files, which the shorter of the two
counted runs would otherwise pay for and the longer reuse.

What cannot be measured (no git, a commit not in the repository, a build or a probe that fails)
is kept under "not_measured" and becomes a row 'not measured' with the reason, never a traceback.
"""

from __future__ import annotations

import json
import os
import platform
import shutil
import sys
import tarfile
import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from hilrig.apps.bench.common import NOT_MEASURED, ROOT, NotMeasured, ProbeError, ratio_of, run_probe, say

DEFAULT_BASELINE = "dbf1cf7"
"""The commit the checkout's engine is compared with when BASELINE is not given: the last one
before the rig's folders became its layers. The one place it is written."""

BASELINE_FOLDER = "baseline"
"""Under the bench build folder: the exported tree of the baseline commit, one folder by hash."""

MODES = ("rig", "engine")
"""The rig_probe.py modes compared: the Rig's whole lockstep cycle, the engine's exchange alone."""

GOAL_WITHIN = 0.10
"""The checkout's instructions per cycle may exceed the baseline's by this share at most."""

GOAL = f"within {GOAL_WITHIN:.0%} (<= {1 + GOAL_WITHIN:g})"

_MARKER = ".bench-baseline.json"
_LABELS = {"rig": "Rig lockstep cycle", "engine": "engine's exchange alone"}
CHECK_CYCLES = 5
"""Cycles of the native run of each mode that checks a tree's probe before it is counted."""

NO_BASELINE = "no baseline in native.json (a native step from before the comparison)"

PerCycle = Callable[[str, Path], float]
"""Instructions per cycle of `tools/rig_probe.py MODE` of the tree at the path (`native`)."""


def resolve_commit(commit: str, repo: Path = ROOT) -> str:
    """The full hash of `commit` in the repository at `repo`; ProbeError saying which when git is
    missing, `repo` is not a git repository (an unpacked release), or the commit is not in it (a
    shallow clone, a mistyped BASELINE)."""
    if shutil.which("git") is None:
        raise ProbeError(f"baseline {commit!r}: git is not installed (apt-get install git)")
    try:
        run_probe(["git", "-C", str(repo), "rev-parse", "--git-dir"], timeout_s=60.0)
    except ProbeError as error:
        raise ProbeError(f"baseline {commit!r}: {repo} is not a git repository: {error}") from error
    try:
        printed = run_probe(
            ["git", "-C", str(repo), "rev-parse", "--verify", "--quiet", f"{commit}^{{commit}}"],
            timeout_s=60.0,
        )
    except ProbeError as error:
        raise ProbeError(f"baseline {commit!r}: no such commit in {repo} ({error})") from error
    return printed.strip()


def baseline_folder(out: Path) -> Path:
    return out / BASELINE_FOLDER


def _marker_data(sha: str) -> dict[str, str]:
    """What the marker of a whole tree holds: a tree built for another Python is built again."""
    return {"commit": sha, "python": sys.executable, "python_version": platform.python_version()}


def _is_whole(tree: Path, sha: str) -> bool:
    try:
        return json.loads((tree / _MARKER).read_text()) == _marker_data(sha)
    except (OSError, ValueError):
        return False


def export_tree(sha: str, out: Path, make_runnable: Callable[[Path], None], *, repo: Path = ROOT) -> Path:
    """The tree of commit `sha` under out/baseline/<sha>/, exported (`git archive`) and made
    runnable by `make_runnable(staging folder)` once; a whole one is reused. Every other folder
    there (another commit's tree, a half-done export) is removed first; an export that fails
    leaves nothing behind."""
    folder = baseline_folder(out)
    tree = folder / sha
    if _is_whole(tree, sha):
        say(f"  baseline {sha[:10]}: reusing {tree}")
        return tree
    folder.mkdir(parents=True, exist_ok=True)
    for entry in folder.iterdir():
        say(f"  baseline: removing {entry}")
        shutil.rmtree(entry) if entry.is_dir() else entry.unlink()
    staging = Path(tempfile.mkdtemp(prefix=f".{sha[:10]}-", dir=folder))
    staging.chmod(0o755)  # as a checkout's folder, not mkdtemp's private one
    try:
        say(f"  baseline {sha[:10]}: exporting the tree (git archive) to {tree}")
        archive = staging / ".tree.tar"
        run_probe(["git", "-C", str(repo), "archive", "--format=tar", f"--output={archive}", sha])
        with tarfile.open(archive) as tar:
            tar.extractall(staging, filter="data")
        archive.unlink()
        if not (staging / "tools" / "rig_probe.py").is_file():
            raise ProbeError(f"baseline {sha[:10]}: the commit has no tools/rig_probe.py to measure")
        make_runnable(staging)
        (staging / _MARKER).write_text(json.dumps(_marker_data(sha)) + "\n")
        staging.rename(tree)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return tree


def ensure_board_files(root: Path, *, always: bool = False) -> None:
    """The EDS (and the rest of build/protocol/) that the fake node of the tree at `root` loads,
    generated by the tree's own boardproto as its CMake does; for the checkout only when missing
    (a checkout where `make build` has not run yet), for an exported tree `always`."""
    out_dir = root / "build" / "protocol"
    if not always and (out_dir / "board.eds").is_file():
        return
    say(f"  generating {out_dir.relative_to(root)}/ of {root} (its own boardproto)")
    run_probe(
        [
            sys.executable,
            "-m",
            "boardproto",
            "generate",
            "--quiet",
            "--table",
            str(root / "protocol" / "board.toml"),
            "--out-dir",
            str(out_dir),
        ],
        env={**os.environ, "PYTHONPATH": str(root / "protocol")},
    )


def make_runnable(tree: Path) -> None:
    """An exported tree made runnable as a checkout is: its C extensions built in place by its
    own setup.py with this Python (the .so files are named for it), its build/protocol/."""
    say("  building its C extensions in place (its rig/setup.py build_ext --inplace)")
    run_probe([sys.executable, "setup.py", "--quiet", "build_ext", "--inplace"], cwd=tree / "rig")
    ensure_board_files(tree, always=True)


_CHECK = """\
import runpy, sys
probe, root = sys.argv[1], sys.argv[2] + "/"
sys.argv = [probe, *sys.argv[3:]]
try:
    runpy.run_path(probe, run_name="__main__")
except SystemExit as stop:
    if stop.code:
        raise
foreign = sorted(
    f"{name} from {module.__file__}"
    for name, module in list(sys.modules.items())
    if name.split(".")[0] in ("hilrig", "boardproto", "dashboards")
    and getattr(module, "__file__", None)
    and not module.__file__.startswith(root)
)
if foreign:
    sys.exit("the probe imported modules from outside its tree: " + "; ".join(foreign[:5]))
"""


def check_probe(root: Path) -> None:
    """The tree's `tools/rig_probe.py` run natively for a few cycles of each mode: it must exit 0
    and import hilrig and boardproto from `root` only (else a ProbeError says what it imported
    from where). Its .pyc files are written then, before any count."""
    root = root.resolve()
    probe = root / "tools" / "rig_probe.py"
    for mode in MODES:
        run_probe([sys.executable, "-c", _CHECK, str(probe), str(root), mode, str(CHECK_CYCLES)])


def prepare_checkout(root: Path = ROOT) -> None:
    """The checkout's probe ready to count, as the baseline's is: its EDS there, its probe checked
    and its .pyc files current."""
    ensure_board_files(root)
    check_probe(root)


def prepare_baseline(out: Path, commit: str, *, repo: Path = ROOT) -> Path:
    """The tree of `commit`, exported once under out/baseline/, runnable and checked."""
    sha = resolve_commit(commit, repo)
    tree = export_tree(sha, out.resolve(), make_runnable, repo=repo)
    check_probe(tree)
    return tree


def remove_baseline(out: Path) -> None:
    """Every exported baseline tree under `out` removed."""
    folder = baseline_folder(out)
    if folder.exists():
        say(f"removing {folder}")
        shutil.rmtree(folder)


def measure_baseline(
    out: Path,
    commit: str,
    not_measured: NotMeasured,
    per_cycle: PerCycle,
) -> dict[str, Any]:
    """The baseline's instructions per cycle of each of MODES, by `per_cycle(mode, its tree)`,
    with the commit asked for and its full hash. What fails leaves its figure out and its reason
    in `not_measured`: "baseline" (the tree: git, the commit, its build, its probe's check) or
    "baseline MODE" (that count)."""
    record: dict[str, Any] = {"asked": commit}
    say(f"the baseline's engine ({commit}): tools/rig_probe.py of that commit, as the checkout's")
    tree = not_measured.attempt("baseline", lambda: prepare_baseline(out, commit))
    if tree is None:
        return record
    record["commit"] = tree.name
    for mode in MODES:
        cost = not_measured.attempt(f"baseline {mode}", lambda mode=mode: per_cycle(mode, tree))
        if cost is not None:
            record[mode] = cost
            say(f"  baseline {mode}: {cost:.0f} instructions per cycle")
    return record


def baseline_rows(
    row: Callable[..., None],
    probe: Mapping[str, float] | None,
    baseline: Mapping[str, Any] | None,
    not_measured: Mapping[str, str],
) -> None:
    """One row per mode: the checkout's instructions per cycle ("ours"), the baseline's, their
    ratio new/old and the goal, met or missed. A figure missing on either side is a row 'not
    measured' with the reasons (the baseline's tree, its count, the checkout's count); a
    native.json without a baseline says so."""
    baseline = baseline or {}
    name = str(baseline.get("commit") or baseline.get("asked") or DEFAULT_BASELINE)[:10]
    for mode in MODES:
        what = f"instructions/cycle (main thread): {_LABELS[mode]}, this checkout vs baseline {name}"
        keys = ("baseline", f"baseline {mode}", f"rig_probe {mode}")
        errors = [not_measured[key] for key in keys if key in not_measured]
        new, old = (probe or {}).get(mode), baseline.get(mode)
        if new is None or old is None:
            errors = errors or [NO_BASELINE if not baseline else f"no figure for {mode} in native.json"]
            row(what, NOT_MEASURED, errors[0].splitlines()[0], None, error="\n".join(errors), **baseline)
            continue
        ratio = ratio_of(new, old)
        row(what, f"{new:.0f}", f"{old:.0f}", ratio, GOAL, ratio <= 1 + GOAL_WITHIN, **baseline)
