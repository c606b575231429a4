"""The workspace of `make mutate` (tools/mutate.py): a copy of the sources (the checkout is never
touched), its build trees (the test configuration the unit tests run in, the release one the
scenarios' firmware comes from), a mutant applied to it and taken back whatever happens, and the
builds run so that Ctrl-C stops them whole."""

from __future__ import annotations

import contextlib
import json
import os
import shlex
import shutil
import signal
import subprocess
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from mutate_mutants import REPO, Mutant, ninja_deps
from mutate_scenarios import SCENARIO_CMAKE_ARGS, SCENARIO_FIRMWARE

CMAKE_ARGS = ("-DCMAKE_BUILD_TYPE=RelWithDebInfo", "-DHIL_SANITIZE=ON", "-DHIL_TESTS=ON")
"""The configuration of `make build`: what `make test` runs."""
SOURCES = ("CMakeLists.txt", "cmake", "firmware", "protocol")
"""What the build needs of the checkout (copied into the workspace)."""


# --- The workspace: a copy of the sources and its build tree ---------------------------------
@dataclass(frozen=True)
class Workspace:
    out: Path
    source_root: Path
    sources: tuple[str, ...] = SOURCES
    cmake_args: tuple[str, ...] = CMAKE_ARGS
    build_name: str = "build"

    @property
    def src(self) -> Path:
        return self.out / "src"

    @property
    def build(self) -> Path:
        return self.out / self.build_name

    def mutant_dir(self, mutant: Mutant) -> Path:
        return self.out / "mutants" / mutant.id

    def sync(self) -> None:
        """Copy what changed of the sources (content compared, so untouched files keep their
        times and the build stays incremental)."""
        for name in self.sources:
            origin = self.source_root / name
            for file in [origin] if origin.is_file() else sorted(p for p in origin.rglob("*") if p.is_file()):
                if "__pycache__" in file.parts:
                    continue
                target = self.src / file.relative_to(self.source_root)
                if target.exists() and target.read_bytes() == file.read_bytes():
                    continue
                target.parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(file, target)

    def configure(self) -> None:
        """Configure the tree once, and again when its configuration changed (kept beside it)."""
        python = REPO / ".venv" / "bin" / "python"
        argv = [
            "cmake",
            "-S",
            str(self.src),
            "-B",
            str(self.build),
            "-G",
            "Ninja",
            f"-DHIL_PYTHON={python}",
            "-DCMAKE_EXPORT_COMPILE_COMMANDS=ON",
            *self.cmake_args,
        ]
        stamp = self.build / "mutate-configure.json"
        if (self.build / "build.ninja").exists() and stamp.exists() and json.loads(stamp.read_text()) == argv:
            return
        run_checked(argv, "configure the mutation build")
        stamp.write_text(json.dumps(argv))

    def known(self, targets: Sequence[str]) -> list[str]:
        """Those of `targets` the configured build has (a board may have no head firmware)."""
        query = ["ninja", "-C", str(self.build), "-t", "query"]
        return [t for t in targets if subprocess.run([*query, t], capture_output=True).returncode == 0]

    def compile(self, jobs: int, targets: Sequence[str] | None = None) -> subprocess.CompletedProcess[str]:
        """Build everything, or only `targets` (outputs relative to the build, e.g. bin/x): what a
        mutant's tests run. A sanitized build's time is mostly linking, and a source of the core
        links into every test executable, bench and fuzzer."""
        chosen = ["--target", *targets] if targets else []
        return run_group(["cmake", "--build", str(self.build), "-j", str(jobs), *chosen])


def run_group(argv: Sequence[str], timeout_s: float | None = None) -> subprocess.CompletedProcess[str]:
    """Run `argv` in a process group of its own, output captured. On Ctrl-C, SIGTERM or the
    timeout the whole group gets SIGINT first, so that ninja deletes what it was writing (a
    compiler killed alone leaves a half-written object file that looks up to date), then
    SIGKILL. subprocess.run would kill only its child and leave the build's processes running."""
    process = subprocess.Popen(
        argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True
    )
    try:
        output, _ = process.communicate(timeout=timeout_s)
    except BaseException:
        stop_group(process, grace_s=10)
        raise
    return subprocess.CompletedProcess(list(argv), process.returncode, output, "")


def stop_group(process: subprocess.Popen, grace_s: float) -> None:
    """SIGINT to the process group `process` leads, SIGKILL if it is not gone after `grace_s`."""
    with contextlib.suppress(ProcessLookupError):
        os.killpg(process.pid, signal.SIGINT)
    try:
        process.communicate(timeout=grace_s)
    except subprocess.TimeoutExpired:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)
        process.communicate()


def run_checked(argv: Sequence[str], what: str) -> None:
    result = subprocess.run(argv, capture_output=True, text=True, check=False)
    if result.returncode != 0:
        tail = "\n".join((result.stdout + result.stderr).splitlines()[-30:])
        raise SystemExit(f"mutate: cannot {what} ({' '.join(argv[:3])} ...):\n{tail}")


@contextlib.contextmanager
def mutated(workspace: Workspace, mutant: Mutant):
    """The mutant's file changed in the workspace for the body; the original back afterwards,
    whatever happens (Ctrl-C included). The body sets `untouched_outputs` when the build failed
    before writing anything of the mutant: a .cpp file's one object file was not rewritten (the
    compiler writes none on an error), so the original gets its old time back and is not
    compiled again for the next mutant. Never for a header: other translation units that
    include it may have compiled the mutant before the error; unless `nothing_built` says that
    only the syntax check saw it."""
    path = workspace.src / mutant.path
    original = path.read_text()
    before = path.stat()
    path.write_text(mutant.apply(original))
    state = {"untouched_outputs": False, "nothing_built": False}
    try:
        yield state
    finally:
        path.write_text(original)
        if state["untouched_outputs"] and (path.suffix == ".cpp" or state["nothing_built"]):
            os.utime(path, ns=(before.st_atime_ns, before.st_mtime_ns))


def syntax_check(workspace: Workspace, mutant: Mutant) -> bool:
    """Whether the mutated file's translation unit (for a header: the first one that includes
    it) passes the compiler's syntax and type check (-fsyntax-only, a fraction of a build): a
    mutant that fails it is dropped without building anything. True when no unit is known."""
    unit = translation_unit_of(workspace, workspace.src / mutant.path)
    if unit is None:
        return True
    argv, directory = unit
    return subprocess.run(argv, cwd=directory, capture_output=True, check=False).returncode == 0


def translation_unit_of(workspace: Workspace, path: Path) -> tuple[list[str], str] | None:
    """The syntax-check command line of the unit that compiles `path`, and its directory."""
    commands_path = workspace.build / "compile_commands.json"
    if not commands_path.exists():
        return None
    commands = {str(Path(e["file"]).resolve()): e for e in json.loads(commands_path.read_text())}
    entry = commands.get(str(path.resolve()))
    if entry is None:  # a header: the first unit built from it that has a command
        for output, sources in ninja_deps(workspace.build).items():
            if path.resolve() in sources:
                entry = next((e for e in commands.values() if e.get("output") == output), None)
                if entry is not None:
                    break
    if entry is None:
        return None
    argv = entry["arguments"] if "arguments" in entry else shlex.split(entry["command"])
    cleaned, skip = [], False
    for arg in argv:
        if skip:
            skip = False
            continue
        if arg in ("-o", "-MF", "-MT", "-MQ"):
            skip = True
            continue
        if arg in ("-c", "-MD", "-MMD"):
            continue
        cleaned.append(arg)
    return [*cleaned, "-fsyntax-only"], entry["directory"]


def scenario_tree_of(workspace: Workspace) -> Workspace:
    """The build tree of the firmware the scenarios run (SCENARIO_CMAKE_ARGS), on the same sources."""
    return Workspace(
        workspace.out, workspace.source_root, workspace.sources, SCENARIO_CMAKE_ARGS, "scenario-build"
    )


def keep_scenario_firmware(scenario_tree: Workspace, binaries: Sequence[str], folder: Path) -> None:
    kept = folder / SCENARIO_FIRMWARE
    kept.mkdir(exist_ok=True)
    for binary in binaries:
        shutil.copy2(scenario_tree.build / binary, kept / Path(binary).name)
