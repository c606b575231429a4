"""Approved traces: every lockstep scenario's run compared, cycle by cycle, with a baseline
committed beside the tests (part of hilrig's pytest plugin).

A lockstep run is bit-identical for the same seed, so whatever the firmware does differently is
visible exactly. What is compared, per run of a scenario (each `make_scenario` call, each module
of a `make_robot`):

* every TPDO the node sent, by COB-ID and mapping: the cycles it came in and its bytes, field by
  field (the actuator outputs and everything else the node publishes);
* every EMCY (cycle, code, register, manufacturer bytes) and every SDO abort the node answered
  the rig's requests with (cycle, code).

Left out, because a wall clock decides them: heartbeats and NMT states seen in them, the TPDOs'
arrival times, the EMCYs a node sends once it has left operational (the rig's SYNCs then go
unanswered, so how many of them the node has taken when its EMCY comes, and which cycle the EMCY
lands in, is the host's timing: the scenario's own assertions judge those), real-time scenarios
(`mode="realtime"`) and real boards (`--hil-interface`).

The baseline is `approved/<module>.<test>.json` beside the test file: the run's layout as text
and its rows as the bus carried them, XOR-delta coded per byte column and compressed (lzma,
base64): exact values, so a difference names its first cycle, its field and both values
(`hilrig diff`'s `Comparison`), at some 1 to 2 bytes per noisy field and cycle.

    pytest --hil-approved=check    (default) a difference fails the scenario, first divergence first
    pytest --hil-approved=update   write the baselines anew; the terminal summary says what changed
    pytest --hil-approved=off      compare nothing (the scenarios' own assertions alone)

A scenario without a baseline: under CI (the `CI` environment variable set, as GitHub Actions
and GitLab CI set it) it fails with the command that writes one; elsewhere it writes it, passes,
and the terminal summary lists it as new, to review and commit. `@pytest.mark.no_approved_trace
("why")` exempts a scenario whose run a wall clock shapes.
"""

from __future__ import annotations

import base64
import json
import lzma
import os
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from hilrig.engine.history import History, HistoryMark, records_dtype
from hilrig.engine.observers import RigObserver
from hilrig.engine.rig import Rig
from hilrig.observe.diff import Comparison, Divergence
from hilrig.pytest_plugin.reports import baseline_path
from hilrig.wire.node import EmcyRecord
from hilrig.wire.transport import PdoDirection

MODES = ("check", "off", "update")
DEFAULT_MODE = "check"
APPROVED_FOLDER = "approved"
"""Beside each test file: tests/approved/test_joint.test_step.json."""
FORMAT = 1
UPDATE_COMMAND = "pytest --hil-approved=update"
"""What writes a baseline anew; a project may name its own wrapper (`hil_approve_command`, e.g.
`make approve K={test}`)."""
MARKER = "no_approved_trace"
MORE_RUNS = 3
"""Runs of a scenario (a robot's modules) a failure spells out; the others are counted."""
_CHANGES_PROPERTY = "hil_approved"
"""The user property a test's report carries what its update changed in (read by the controller
of an xdist run too)."""
_TRACES = pytest.StashKey[list["ApprovedRecorder"]]()


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("hil")
    group.addoption(
        "--hil-approved",
        choices=MODES,
        default=DEFAULT_MODE,
        help="compare each lockstep scenario with its approved trace (approved/<test>.json beside "
        "it): check (default: a difference fails), update (write them anew, say what changed), "
        "off (compare nothing)",
    )
    parser.addini(
        "hil_approve_command",
        "the command that approves a scenario's trace, named in its failure; {nodeid} and {test} "
        "are filled in (default: pytest --hil-approved=update {nodeid})",
        default="",
    )


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        f"{MARKER}(reason): the scenario's run depends on a wall clock; no approved trace is compared",
    )


# --- What a run records ---------------------------------------------------------------------
class ApprovedRecorder(RigObserver):
    """What one run contributes: its history (the TPDO rows), the EMCYs and SDO aborts as they
    arrive; attached to a rig right after it starts (`watch`)."""

    def __init__(self, name: str, in_lockstep: Callable[[], bool] = lambda: True) -> None:
        self.name = name
        self.in_lockstep = in_lockstep
        """Whether the rig and the node are in lockstep now (the node operational)."""
        self.history: History | None = None
        self.emcy: list[tuple[int, int, int, str]] = []
        self.aborts: list[tuple[int, int]] = []

    def on_history(self, history: History) -> None:
        self.history = history

    def on_emcy(self, record: EmcyRecord) -> None:
        # The EMCY that ends lockstep (a heartbeat event) comes while it still holds: it counts.
        if self.in_lockstep():
            self.emcy.append((record.cycle, record.code, record.register, record.data.hex()))

    def on_sdo_abort(self, what: str, code: int, *, cycle: int, t: float) -> None:
        self.aborts.append((cycle, code))

    def run(self) -> Run:
        assert self.history is not None
        end = self.history.mark()
        pdos = []
        for layout, cycles, matrix in self.history.blocks_between(HistoryMark({}, 0), end):
            if layout.direction is not PdoDirection.TPDO:
                continue
            rows = np.empty(len(cycles), dtype=records_dtype(layout.formats))
            for i, name in enumerate(rows.dtype.names or ()):
                rows[name] = matrix[:, i]
            pdos.append(Rows(f"0x{layout.cob_id:03X}", layout.names, layout.formats, cycles, rows))
        pdos.sort(key=lambda p: (p.cob_id, p.names))
        return Run(
            self.name, self.history.period_us, self.history.cycles, pdos, list(self.emcy), list(self.aborts)
        )


def watch(item: pytest.Item, rig: Rig, name: str) -> None:
    """Record `rig`'s run for the approved trace of `item` (the plugin's fixtures call it for each
    lockstep run; a project's own fixture may too)."""
    if item.config.getoption("hil_approved") == "off":
        return
    recorder = ApprovedRecorder(name, lambda: bool(getattr(rig.driver, "operational", True)))
    rig.add_observer(recorder)
    item.stash.setdefault(_TRACES, []).append(recorder)


@dataclass
class Rows:
    """One TPDO's rows: the cycles it came in and what it carried (a record array, `v<i>` the
    i-th mapped object, in its bus type)."""

    cob_id: str
    names: tuple[str, ...]
    formats: tuple[str, ...]
    cycles: np.ndarray
    rows: np.ndarray

    @property
    def key(self) -> str:
        return f"TPDO {self.cob_id} ({', '.join(self.names)})"


@dataclass
class Run:
    name: str
    period_us: int
    cycles: int
    pdos: list[Rows]
    emcy: list[tuple[int, int, int, str]] = field(default_factory=list)
    aborts: list[tuple[int, int]] = field(default_factory=list)


# --- The file ---------------------------------------------------------------------------------
def _pack(pdos: Sequence[Rows]) -> str:
    """Every PDO's cycles (deltas, int32) and rows (each byte column XOR its previous row, column
    by column: a field that holds still is a run of zeros), lzma-compressed, base64."""
    parts = []
    for pdo in pdos:
        parts.append(np.diff(pdo.cycles, prepend=0).astype("<i4").tobytes())
        width = pdo.rows.dtype.itemsize
        raw = np.frombuffer(pdo.rows.tobytes(), dtype=np.uint8).reshape(len(pdo.rows), width)
        delta = raw.copy()
        delta[1:] ^= raw[:-1]
        parts.append(delta.T.tobytes())
    return base64.b64encode(lzma.compress(b"".join(parts))).decode()


def _unpack(text: str, layouts: Sequence[tuple[str, tuple[str, ...], tuple[str, ...], int]]) -> list[Rows]:
    blob = lzma.decompress(base64.b64decode(text))
    offset = 0
    pdos = []
    for cob_id, names, formats, count in layouts:
        cycles = np.cumsum(np.frombuffer(blob, dtype="<i4", count=count, offset=offset)).astype(np.int64)
        offset += 4 * count
        dtype = records_dtype(formats)
        width = dtype.itemsize
        columns = np.frombuffer(blob, dtype=np.uint8, count=count * width, offset=offset)
        offset += count * width
        raw = np.bitwise_xor.accumulate(columns.reshape(width, count).T, axis=0)
        pdos.append(Rows(cob_id, names, formats, cycles, np.frombuffer(raw.tobytes(), dtype=dtype)))
    return pdos


def to_json(test: str, runs: Sequence[Run]) -> str:
    document = {
        "format": FORMAT,
        "test": test,
        "runs": [
            {
                "name": run.name,
                "period_us": run.period_us,
                "cycles": run.cycles,
                "tpdos": [
                    {
                        "cob_id": p.cob_id,
                        "names": list(p.names),
                        "formats": list(p.formats),
                        "rows": len(p.rows),
                    }
                    for p in run.pdos
                ],
                "emcy": [list(e) for e in run.emcy],
                "sdo_aborts": [list(a) for a in run.aborts],
                "data": _pack(run.pdos),
            }
            for run in runs
        ],
    }
    return json.dumps(document, indent=1) + "\n"


def from_json(text: str) -> list[Run]:
    document = json.loads(text)
    if document.get("format") != FORMAT:
        raise ValueError(f"format {document.get('format')!r}, not {FORMAT}")
    runs = []
    for entry in document["runs"]:
        layouts = [(t["cob_id"], tuple(t["names"]), tuple(t["formats"]), t["rows"]) for t in entry["tpdos"]]
        runs.append(
            Run(
                entry["name"],
                entry["period_us"],
                entry["cycles"],
                _unpack(entry["data"], layouts),
                [tuple(e) for e in entry["emcy"]],  # type: ignore[misc]
                [tuple(a) for a in entry["sdo_aborts"]],  # type: ignore[misc]
            )
        )
    return runs


# --- The comparison ---------------------------------------------------------------------------
def _value(rows: np.ndarray, row: int, position: int) -> float:
    return float(rows[f"v{position}"][row])


def _pdo_divergences(base: Rows, cand: Rows, time_of: object) -> list[Divergence]:
    """Each field's first differing row, and where the TPDO came in one run's cycle but not the
    other's (rows compared up to there)."""
    assert callable(time_of)
    common = min(len(base.cycles), len(cand.cycles))
    apart = np.nonzero(base.cycles[:common] != cand.cycles[:common])[0]
    aligned = int(apart[0]) if len(apart) else common
    found = []
    for position, name in enumerate(base.names):
        b = np.ascontiguousarray(base.rows[f"v{position}"][:aligned]).view(np.uint8).reshape(aligned, -1)
        c = np.ascontiguousarray(cand.rows[f"v{position}"][:aligned]).view(np.uint8).reshape(aligned, -1)
        differs = np.nonzero((b != c).any(axis=1))[0]
        if len(differs):
            row = int(differs[0])
            cycle = int(base.cycles[row])
            found.append(
                Divergence(
                    f"tpdo/{base.cob_id}/{name}",
                    name,
                    cycle,
                    time_of(cycle),
                    _value(base.rows, row, position),
                    _value(cand.rows, row, position),
                )
            )
    if aligned < max(len(base.cycles), len(cand.cycles)):

        def at(pdo: Rows) -> int | None:
            return int(pdo.cycles[aligned]) if aligned < len(pdo.cycles) else None

        cb, cc = at(base), at(cand)
        cycle = min(c for c in (cb, cc) if c is not None)
        words = {True: "sent", False: "not sent"}
        found.append(
            Divergence(
                f"tpdo/{base.cob_id}",
                f"TPDO {base.cob_id}",
                cycle,
                time_of(cycle),
                words[cb == cycle],
                words[cc == cycle],
            )
        )
    return found


def _list_divergence(
    path: str, base: Sequence[tuple], cand: Sequence[tuple], time_of: object
) -> Divergence | None:
    """The first entry where two lists of (cycle, ...) entries part."""
    assert callable(time_of)
    missing = "(none)"
    for index in range(max(len(base), len(cand))):
        b = base[index] if index < len(base) else None
        c = cand[index] if index < len(cand) else None
        if b != c:
            cycle = min(int(e[0]) for e in (b, c) if e is not None)
            return Divergence(path, path, cycle, time_of(cycle), _entry(b) or missing, _entry(c) or missing)
    return None


def _entry(entry: tuple | None) -> str | None:
    if entry is None:
        return None
    cycle, code, *rest = entry
    code_text = f"0x{code:04X}" if code <= 0xFFFF else f"0x{code:08X}"
    return " ".join([f"cycle {cycle}", code_text, *map(str, rest)])


def compare_runs(base: Run, cand: Run) -> Comparison:
    """`hilrig diff`'s comparison of two runs' approved traces: every diverging series by its
    first divergence, earliest first."""
    period_s = base.period_us / 1e6

    def time_of(cycle: int) -> float:
        return cycle * period_s

    base_pdos = {p.key: p for p in base.pdos}
    cand_pdos = {p.key: p for p in cand.pdos}
    divergences: list[Divergence] = []
    for key in sorted(base_pdos.keys() & cand_pdos.keys()):
        divergences += _pdo_divergences(base_pdos[key], cand_pdos[key], time_of)
    for path, b, c in (("emcy", base.emcy, cand.emcy), ("sdo abort", base.aborts, cand.aborts)):
        found = _list_divergence(path, b, c, time_of)
        if found is not None:
            divergences.append(found)
    if base.cycles != cand.cycles and not divergences:
        end = min(base.cycles, cand.cycles)
        divergences.append(Divergence("cycles", "cycles run", end, time_of(end), base.cycles, cand.cycles))
    divergences.sort(key=lambda d: d.cycle)
    return Comparison(
        compared=[*sorted(base_pdos.keys() & cand_pdos.keys()), "emcy", "sdo abort"],
        divergences=divergences,
        only_base=sorted(base_pdos.keys() - cand_pdos.keys()),
        only_cand=sorted(cand_pdos.keys() - base_pdos.keys()),
        base_cycles=(0, base.cycles - 1),
        cand_cycles=(0, cand.cycles - 1),
        period_s=period_s,
    )


def compare_traces(base: Sequence[Run], cand: Sequence[Run], *, every: bool = False) -> list[str]:
    """What differs between an approved trace and a new one, run by run (empty: nothing): the
    lines `hilrig diff` prints for each run that differs (its first MORE_RUNS); `every`: every
    run that differs and every series that moved in it, each at its first divergence (what an
    update shows for review)."""
    lines: list[str] = []
    if [r.name for r in base] != [r.name for r in cand]:
        lines.append(f"runs: approved {[r.name for r in base]}, this run {[r.name for r in cand]}")
    differing = 0
    for b, c in zip(base, cand, strict=False):
        comparison = compare_runs(b, c)
        if comparison.same:
            continue
        differing += 1
        if not every and differing > MORE_RUNS:
            continue
        head = f"run {c.name}: " if len(cand) > 1 or c.name != "main" else ""
        summary = comparison.summary()
        lines.append(head + summary[0])
        if every:
            lines += [f"  {divergence}" for divergence in comparison.divergences]
            lines += [f"  {line}" for line in summary[2:] if line.startswith("only in ")]
        elif head:
            lines += ["  " + line if not line.startswith("  ") else line for line in summary[1:]]
        else:
            lines += summary[1:]
    if differing > MORE_RUNS and not every:
        lines.append(f"... and {differing - MORE_RUNS} more runs differ")
    return lines


# --- The hooks ----------------------------------------------------------------------------------
def approved_path(item: pytest.Item) -> Path:
    return baseline_path(Path(item.path).parent / APPROVED_FOLDER, item.nodeid, suffix=".json")


def _command(config: pytest.Config, item: pytest.Item) -> str:
    """The one command that approves `item`'s trace: the project's `hil_approve_command`, with
    {nodeid} and {test} (the test function's name) filled in, else pytest's own."""
    spelled = str(config.getini("hil_approve_command") or "").strip()
    if not spelled:
        return f"{UPDATE_COMMAND} {item.nodeid}"
    return spelled.replace("{nodeid}", item.nodeid).replace(
        "{test}", getattr(item, "originalname", item.name)
    )


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item: pytest.Item) -> Iterator[None]:
    """After a scenario's own assertions passed, its runs against the approved trace."""
    result = yield
    recorders = item.stash.get(_TRACES, [])
    mode = item.config.getoption("hil_approved")
    if not recorders or mode == "off" or item.get_closest_marker(MARKER) is not None:
        return result
    runs = [recorder.run() for recorder in recorders]
    path = _shown(approved_path(item), item.config)
    text = to_json(item.nodeid, runs)
    try:
        approved = from_json(path.read_text()) if path.is_file() else None
    except (OSError, ValueError, KeyError) as error:
        if mode != "update":
            command = _command(item.config, item)
            pytest.fail(f"approved trace {path} unreadable ({error}): {command}", pytrace=False)
        approved = None
    if approved is None:
        if mode != "update" and os.environ.get("CI"):
            pytest.fail(
                f"no approved trace {path}: run `{_command(item.config, item)}`, review it and commit it",
                pytrace=False,
            )
        _write(path, text)
        item.user_properties.append((_CHANGES_PROPERTY, f"new {path}"))
        return result
    differences = compare_traces(approved, runs)
    if not differences:
        return result
    if mode == "update":
        _write(path, text)
        changes = compare_traces(approved, runs, every=True)
        item.user_properties.append((_CHANGES_PROPERTY, "\n".join([f"changed {path}", *changes])))
        return result
    pytest.fail(
        "\n".join(
            [
                f"the run differs from its approved trace {path}:",
                *differences,
                f"if the change is intended: `{_command(item.config, item)}`, review and commit",
            ]
        ),
        pytrace=False,
    )


def _shown(path: Path, config: pytest.Config) -> Path:
    """The path relative to the run's root folder when it is inside it (as a report names it)."""
    try:
        return path.resolve().relative_to(Path.cwd())
    except ValueError:
        return path


def _write(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.with_suffix(f".{os.getpid()}.tmp")
    temporary.write_text(text)
    temporary.replace(path)


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    lines = [
        f"{report.nodeid}: {value}"
        for reports in terminalreporter.stats.values()
        for report in reports
        if getattr(report, "when", None) == "call"
        for name, value in getattr(report, "user_properties", ())
        if name == _CHANGES_PROPERTY
    ]
    if lines:
        terminalreporter.section("approved traces written: review and commit them")
        for line in lines:
            terminalreporter.line(line)


__all__ = [
    "APPROVED_FOLDER",
    "DEFAULT_MODE",
    "MARKER",
    "MODES",
    "ApprovedRecorder",
    "Run",
    "approved_path",
    "compare_runs",
    "compare_traces",
    "from_json",
    "pytest_addoption",
    "pytest_configure",
    "pytest_runtest_call",
    "pytest_terminal_summary",
    "to_json",
    "watch",
]
