"""A bench measurement's time budget (`hilrig.apps.bench.common.run_within`): the Rig on the
in-process fake node, the bench's clock simulated (one second a look), so that the cycles run
and where the measurement stops do not depend on this host's speed."""

from __future__ import annotations

import itertools
from collections.abc import Iterator

import can
import pytest

from hilrig.apps.bench import common
from hilrig.engine.rig import Rig
from hilrig.session.fake_node import FakeJointNode
from hilrig.table import RigTable


@pytest.fixture
def rig(channel: str) -> Iterator[Rig]:
    table = RigTable.load()
    rig_bus, fake_bus = (can.Bus(interface="virtual", channel=channel) for _ in range(2))
    fake = FakeJointNode(fake_bus, table=table)
    fake.boot()
    rig = Rig(rig_bus, table=table, seed=1, tpdo_timeout_s=5.0, activity=fake.activity)
    try:
        rig.start()
        yield rig
    finally:
        rig.close()
        fake.close()
        rig_bus.shutdown()
        fake_bus.shutdown()


@pytest.fixture
def clock(monkeypatch: pytest.MonkeyPatch) -> None:
    """perf_counter as the bench sees it: 0 at the start, one second later at each look."""
    ticks = itertools.count()
    monkeypatch.setattr(common, "perf_counter", lambda: float(next(ticks)))


def test_no_cycle_starts_past_the_budget_and_the_count_says_how_many_ran(rig: Rig, clock: None) -> None:
    finished: list[int] = []
    done, elapsed = common.run_within(rig, 10.5, 1000, finish=lambda: finished.append(rig.cycle))
    # looks at 1..10 s let a cycle start each, the one at 11 s does not
    assert (done, rig.cycle, finished) == (10, 10, [10])
    assert elapsed == 12.0  # finish() is inside the time


def test_a_measurement_within_its_budget_runs_all_its_cycles_and_the_rig_runs_on(
    rig: Rig, clock: None
) -> None:
    assert common.run_within(rig, 100.0, 20) == (20, 21.0)
    rig.run(cycles=5)  # the look stays the rig's, disarmed: later cycles are not measured
    assert rig.cycle == 25
