"""Every dashboard in the web viewer, in headless Chromium, on traces of the real firmware: the
ones three scenarios of the bus stage wrote (tools/run-tests runs this after that stage, natively).

For each trace, every dashboard made for it (`hilrig.observe.dashboard_check.fitting_dashboards`:
the five of one joint, `robot`, or `diff` for a comparison of two runs) is shown one after another
in one page (`hilrig.observe.browser.check_dashboards`):
the viewer shows exactly the dashboard's views, none hidden or reporting an error, the recording
whole, something plotted, no console error; every series each view names has data in the
trace; and every series of every plot draws pixels of its own colour inside its own view
(`hilrig.observe.series_check`, a few views to a showing). Screenshots:
$HIL_OUT_DIR/viewer/<trace>/<dashboard>.png, and per showing <trace>/<dashboard>/<view numbers>.png
(`1+2+3.png`).

    .venv/bin/python -m pytest tests/browser        # after the bus stage (make test) wrote them
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from hilrig.observe.browser import ViewerPage, browser_missing, check_dashboards, served_trace
from hilrig.observe.dashboard_check import fitting_dashboards, trace_gaps
from hilrig.observe.reader import Trace
from hilrig.observe.series_check import check_series

REPO = Path(__file__).resolve().parents[2]
FIRMWARE_TRACES = {
    # tests/test_trace_recording.py: each control mode, an SDO abort, an EMCY, fields polled.
    "joint": "test_every_series_every_dashboard_names_has_data_on_a_firmware_trace/trace.rrd",
    # tests/test_robot.py: 8 modules in a travelling wave, the chain in 3D.
    "robot": "test_travelling_wave_tracked_by_all_eight_modules/trace.rrd",
    # tests/test_robot.py: 4 modules, the master's heartbeat stops, each module goes safe.
    "robot4": "test_master_heartbeat_lost_every_module_safe_within_the_consumer_time/trace.rrd",
    # tests/test_determinism.py: `hilrig diff` of two runs with another velocity_kp.
    "diff": "test_same_seed_same_trace_bit_for_bit_other_seed_other_noise/diff.rrd",
}
"""Trace name -> the recording of the bus stage it is (under its scenario's folder)."""
ALONE = "joint"
"""The trace whose dashboards take about as long as the three others' together (five of them):
it has a worker to itself, the others share the second (pytest-xdist groups, `--dist
loadgroup` in tools/run-tests). Dealt out by xdist's own scheduling, the joint and robot4 shared
a worker while the other ran out of work."""
CASES = [
    pytest.param(name, marks=pytest.mark.xdist_group("alone" if name == ALONE else "together"))
    for name in FIRMWARE_TRACES
]


def output_root() -> Path:
    return Path(os.environ.get("HIL_OUT_DIR", REPO / "out"))


@pytest.mark.timeout(1800)
@pytest.mark.parametrize("name", CASES)
def test_every_dashboard_shows_the_firmware_trace_whole(name: str) -> None:
    scenario, _, file_name = FIRMWARE_TRACES[name].partition("/")
    trace_path = output_root() / "scenarios" / scenario / file_name
    if not trace_path.exists():
        if os.environ.get("HIL_SHARD"):
            pytest.skip(f"{scenario} ran in another shard (HIL_SHARD={os.environ['HIL_SHARD']})")
        pytest.fail(
            f"no {trace_path}: the bus stage writes it (make test, or: tools/with-vcan -- "
            f".venv/bin/python -m pytest tests -k {scenario})",
            pytrace=False,
        )
    missing = browser_missing()
    assert missing is None, missing
    trace = Trace.read(trace_path)
    dashboards = fitting_dashboards(trace)
    gaps = trace_gaps(trace, dashboards)
    assert gaps == [], f"{trace_path}: series without data:\n" + "\n".join(gaps)

    # The trace holds overview (robot) as its default: served first is another one where there
    # is one, which must win over it (`hilrig view --dashboard`), the rest are sent in turn.
    names = list(reversed(dashboards))
    out = output_root() / "viewer" / name
    checked: dict[tuple[str, tuple[str, ...]], dict[str, int]] = {}
    with served_trace(trace_path, names[0]) as served, ViewerPage(served) as viewer:
        shown = check_dashboards(trace_path, names, out, viewer=viewer)
        drawn = [
            check_series(
                viewer,
                dashboards[dashboard],
                trace,
                out / dashboard,
                name=dashboard,
                trace_path=trace_path,
                checked=checked,
            )
            for dashboard in names
        ]
    assert list(shown) == names
    problems = {dashboard: result.problems() for dashboard, result in shown.items() if result.problems()}
    assert not problems, problems
    assert all(result.pixels for result in drawn), "every dashboard here plots series"
    undrawn = [line for result in drawn for line in result.missing()]
    assert undrawn == [], f"{out}: series drawing nothing in their view:\n" + "\n".join(undrawn)
