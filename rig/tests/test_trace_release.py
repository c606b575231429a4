"""What Rerun keeps of a trace once it is closed: nothing running. Rerun keeps every stream of
the process with its threads until it is let go of and swept (`hilrig.observe.streams`), so a
process running one traced session after another (a test session, `make bench`) would gain
threads with every one."""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import pytest
from fake_rig import traced_fake_rig

from hilrig.errors import FieldNameError
from hilrig.observe import streams
from hilrig.observe.browser import free_port
from hilrig.observe.reader import Trace
from hilrig.observe.sinks import TraceSink
from hilrig.observe.tracer import Tracer
from hilrig.table import RigTable

SESSIONS = 8
CYCLES = 30
SLACK = 2
"""Threads besides Rerun's that may come and go between two counts: the fake node's heartbeat
(python-can's cyclic send task, not joined when stopped, ends at its next period)."""


@pytest.fixture(scope="module")
def table() -> RigTable:
    return RigTable.load()


def _native_threads() -> int:
    """The process's threads, Rerun's (native, unknown to `threading`) included."""
    return len(os.listdir("/proc/self/task"))


def _traced_session(out_dir: Path, table: RigTable) -> None:
    """A scenario as the pytest plugin runs one: its tracer (with the default dashboard), a Rig
    started and run, everything closed."""
    with traced_fake_rig(Tracer.for_scenario(out_dir, table), table) as rig:
        rig.run(cycles=CYCLES)


def test_traced_sessions_one_after_another_leave_no_threads_behind(tmp_path: Path, table: RigTable) -> None:
    _traced_session(tmp_path / "s0", table)
    after_first = _native_threads()
    for k in range(1, SESSIONS):
        _traced_session(tmp_path / f"s{k}", table)
    after_all = _native_threads()
    assert after_all <= after_first + SLACK, (
        f"{SESSIONS} traced sessions: {after_all} threads, {after_first} after the first"
    )
    for k in range(SESSIONS):  # and each trace is whole: every cycle, the file's footer
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # "RRD file has no footer"
            trace = Trace.read(tmp_path / f"s{k}" / "trace.rrd")
        [duty] = [path for path in trace.scalars if path.endswith("/motor_duty_command")]
        assert len(trace.cycles[duty]) == CYCLES, k


def test_nothing_is_swept_while_a_stream_to_a_viewer_is_live() -> None:
    # The sweep flushes every stream and waits: a viewer not reachable would hold it up.
    with streams.live():
        assert not streams.release()
    assert streams.release()
    with pytest.raises(RuntimeError, match="without go_live"):
        streams.end_live()


def test_a_live_tracer_that_fails_to_start_does_not_hold_the_sweeps_back(table: RigTable) -> None:
    sink = TraceSink.connect(f"rerun+http://127.0.0.1:{free_port()}/proxy")  # no viewer there
    with pytest.raises(FieldNameError):
        Tracer(sink, table, blueprint="overveiw")
    assert streams.release()
