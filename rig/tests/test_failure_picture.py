"""A picture with every failure: a scenario that fails on purpose, run by pytest inside pytest
(`pytester`), leaves a PNG of the field against its band and the moment it failed, named in the
failure, attached to the JUnit XML, listed at the end of the run; and the PNG holds the curve, the
band and the failure line where a check without a browser can find them."""

from __future__ import annotations

import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from hilrig.expect import Expect, FailedCheck, ScenarioAssertion
from hilrig.observe.picture import BAND, BAND_ALPHA, CURVE, FAILED_AT, FailurePictures, draw
from hilrig.pytest_plugin import baseline_path

FAILING_SCENARIO = '''
import can
from pathlib import Path

from hilrig.engine.rig import Rig
from hilrig.expect import Expect
from hilrig.observe.picture import FailurePictures
from hilrig.plants import JointParams
from hilrig.session.fake_node import FakeJointNode
from hilrig.table import RigTable


def test_velocity_step_that_cannot_settle(tmp_path):
    table = RigTable.load()
    rig_bus, fake_bus = (can.Bus(interface="virtual", channel="picture") for _ in range(2))
    fake = FakeJointNode(fake_bus, table=table)
    rig = Rig(
        rig_bus, table=table, params=JointParams.fast_thermal(), seed=3, tpdo_timeout_s=0.5,
        activity=fake.activity,
    )
    fake.boot()
    try:
        rig.start()
        rig.set("velocity_setpoint", 5.0)
        rig.run(cycles=60)
        expect = Expect(rig, evidence="bus log nowhere", picture=FailurePictures(Path("{pictures}")))
        # The fake node's velocity ramps (no physics): at 0.03 s it is far below the band.
        expect.settles_within("output_velocity", target=100.0, tolerance=0.2, by_s=0.03)
    finally:
        rig.close()
        fake.close()
        rig_bus.shutdown()
        fake_bus.shutdown()
'''


def colour(hex_colour: str, alpha: float = 1.0) -> np.ndarray:
    """The RGB a colour is drawn with over white at `alpha`."""
    rgb = np.array([int(hex_colour[i : i + 2], 16) for i in (1, 3, 5)], dtype=float)
    return np.round(alpha * rgb + (1.0 - alpha) * 255.0)


def pixels_of(image: np.ndarray, rgb: np.ndarray, tolerance: float = 12.0) -> np.ndarray:
    """(row, column) of every pixel within `tolerance` of `rgb`."""
    return np.argwhere(np.abs(image.astype(float) - rgb).max(axis=2) <= tolerance)


def test_a_failing_scenario_leaves_a_picture_attached_to_junit(
    pytester: pytest.Pytester, tmp_path: Path
) -> None:
    pictures = tmp_path / "pictures"
    pytester.makeini("[pytest]\njunit_logging = system-out\n")
    pytester.makepyfile(test_failing=FAILING_SCENARIO.replace("{pictures}", str(pictures)))
    junit = tmp_path / "junit.xml"
    result = pytester.runpytest("-p", "no:cacheprovider", f"--junitxml={junit}")
    result.assert_outcomes(failed=1)

    png = pictures / "output_velocity-settles_within.png"
    assert png.is_file()
    result.stdout.fnmatch_lines([f"*picture {png}*", "*failed scenarios: pictures and comparisons*"])
    system_out = "".join(element.text or "" for element in ET.parse(junit).iter("system-out"))
    assert f"[[ATTACHMENT|{png.resolve()}]]" in system_out

    image = np.asarray(Image.open(png).convert("RGB"))
    curve = pixels_of(image, colour(CURVE))
    band = pixels_of(image, colour(BAND, BAND_ALPHA), tolerance=4.0)  # 80 .. 120: a wide fill
    failed_at = pixels_of(image, colour(FAILED_AT))
    assert len(curve) > 200, "the field's curve is not drawn"
    assert len(band) > 2000, "the expected band is not drawn"
    assert len(failed_at) > 100, "the moment of failure is not drawn"
    # The failure line is one vertical line: its pixels share (almost) one column.
    _, counts = np.unique(failed_at[:, 1], return_counts=True)
    assert counts.max() > 0.5 * (image.shape[0] * 0.5), "no vertical failure line"
    # The band starts at by_s = 0.03 s: right of the curve's start.
    assert band[:, 1].min() > curve[:, 1].min()


def test_each_check_draws_its_own_picture(tmp_path: Path) -> None:
    t = np.arange(100) * 0.001

    class History:
        period_s = 0.001

        def history(self, name: str) -> tuple[np.ndarray, np.ndarray]:
            return t, np.sin(t * 50)

    drawn = FailurePictures(tmp_path)
    expect = Expect(History(), picture=drawn)
    for check in (
        lambda: expect.stays_within("x", -0.5, 0.5),
        lambda: expect.stays_within("x", -0.5, 0.5),
        lambda: expect.never("x", lambda v: v > 0.9, "above 0.9"),
        lambda: expect.eventually("x", lambda v: v > 2, "above 2"),
    ):
        with pytest.raises(ScenarioAssertion) as failure:
            check()
        assert failure.value.pictures and f"picture {failure.value.pictures[0]}" in str(failure.value)
    assert [p.name for p in drawn.drawn] == [
        "x-stays_within.png",
        "x-stays_within-2.png",
        "x-never.png",
        "x-eventually.png",
    ]


def test_a_picture_is_written_whole(tmp_path: Path) -> None:
    series = (np.arange(3.0), np.arange(3.0))
    failed = FailedCheck("stays_within", "x", *series, (0.0, 1.0), 0.0, 2.0, "x: failed")
    path = draw(failed, tmp_path / "deep" / "x.png")
    assert Image.open(path).format == "PNG"
    assert [p.name for p in path.parent.iterdir()] == ["x.png"]


def test_baseline_names_are_one_file_per_test(tmp_path: Path) -> None:
    kept = baseline_path(tmp_path, "tests/test_joint.py::test_step[a b]")
    assert kept == tmp_path / "test_joint.test_step_a_b_.rrd"


BASELINE_SCENARIO = '''
import os
from pathlib import Path


def test_run(request, tmp_path):
    trace = tmp_path / "trace.rrd"
    trace.write_bytes(b"run " + os.environ["RUN"].encode())
    request.node.hil_trace = trace
    assert os.environ["RUN"] == "good"
'''


def test_a_baseline_is_kept_when_passing_and_named_when_failing(
    pytester: pytest.Pytester, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    baseline = tmp_path / "baseline"
    pytester.makepyfile(test_kept=BASELINE_SCENARIO)
    monkeypatch.setenv("RUN", "good")
    pytester.runpytest("-p", "no:cacheprovider", f"--hil-baseline={baseline}").assert_outcomes(passed=1)
    kept = baseline / "test_kept.test_run.rrd"
    assert kept.read_bytes() == b"run good"

    monkeypatch.setenv("RUN", "bad")
    failed = pytester.runpytest("-p", "no:cacheprovider", f"--hil-baseline={baseline}")
    failed.assert_outcomes(failed=1)
    failed.stdout.fnmatch_lines([f"*what changed: hilrig diff {kept} *trace.rrd"])
    assert kept.read_bytes() == b"run good"  # a failing run never replaces the last good one


def test_without_matplotlib_the_failure_keeps_its_text_and_says_what_to_install(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    class Recorded:
        period_s = 0.001

        def history(self, name: str) -> tuple[np.ndarray, np.ndarray]:
            return np.arange(100) * 0.001, np.full(100, 3.0)

    monkeypatch.setitem(sys.modules, "matplotlib", None)  # `import matplotlib` raises ImportError
    expect = Expect(Recorded(), evidence="trace t.rrd", picture=FailurePictures(tmp_path / "pictures"))
    with pytest.raises(ScenarioAssertion) as failed:
        expect.stays_within("output_velocity", 0.0, 1.0)
    message = str(failed.value)
    assert message.startswith("output_velocity: expected within [0, 1], got 3 at t = 0.000 s")
    assert "; no picture: matplotlib is not installed (pip install 'hilrig[pytest]'); trace t.rrd" in message
    assert failed.value.pictures == () and not (tmp_path / "pictures").exists()
