"""The lockstep hang guard: when a wait for due TPDOs ends, told from the firmware process's
activity (a scripted sequence here, one value per quiet slice), and /proc's stat line read."""

from __future__ import annotations

import os
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from hilrig.engine.driver import ProcessActivity, _stat_activity, process_activity, thread_activity
from hilrig.engine.lockstep import HANG_CAP_FACTOR, HangGuard
from hilrig.errors import HostStarvedError

TIMEOUT_S = 1.0
SLICE_S = 0.25


def scripted(activities: list[ProcessActivity]) -> tuple[HangGuard, Iterator[str | None]]:
    """A guard over `activities` (the first is read when the guard is made) and its verdicts,
    one per further slice."""
    it = iter(activities)
    guard = HangGuard(TIMEOUT_S, lambda: next(it), SLICE_S)
    return guard, (guard.check(SLICE_S) for _ in activities[1:])


def verdicts(activities: list[ProcessActivity]) -> list[str | None]:
    _, checks = scripted(activities)
    return list(checks)


def test_without_a_process_view_it_is_wall_time() -> None:
    guard = HangGuard(TIMEOUT_S, None, SLICE_S)
    assert [guard.check(SLICE_S) for _ in range(3)] == [None, None, " within 1 s"]


def test_a_process_that_is_gone_falls_back_to_wall_time() -> None:
    guard = HangGuard(TIMEOUT_S, lambda: None, SLICE_S)
    assert [guard.check(SLICE_S) for _ in range(3)] == [None, None, " within 1 s"]


def test_a_firmware_asleep_without_cpu_for_the_timeout_is_a_verdict() -> None:
    asleep = [ProcessActivity(2.0 + 0.001 * k, sleeping=True) for k in range(6)]
    got = verdicts(asleep)
    assert got[:3] == [None, None, None]
    assert got[3] == ": the firmware sat idle for 1 s with them due (1.25 s waited in all)"


def test_idle_must_be_in_a_row() -> None:
    # Asleep, then working for a slice (the queue it drains), then asleep again: idle restarts.
    pattern = [True, True, True, False, True, True, True, True]
    cpu = [1.0, 1.0, 1.0, 1.0, 1.2, 1.2, 1.2, 1.2, 1.2]
    got = verdicts([ProcessActivity(c, s) for c, s in zip(cpu, [True, *pattern], strict=True)])
    assert got[:7] == [None] * 7
    assert got[7] is not None and "sat idle for 1 s" in got[7]


def test_a_firmware_that_burns_the_timeout_in_cpu_without_answering_is_a_verdict() -> None:
    spinning = [ProcessActivity(5.0 + SLICE_S * k, sleeping=False) for k in range(6)]
    got = verdicts(spinning)
    assert got[:3] == [None, None, None]
    assert got[3] is not None and got[3].startswith(
        ": the firmware used 1 s of CPU in 1.25 s without answering"
    )


def test_a_starved_host_is_waited_for_then_named_not_the_firmware() -> None:
    # Runnable, with the SYNC to handle, and barely any CPU given: the host's fault. (A node
    # that gets its CPU answers within milliseconds of it; one that used the timeout in CPU
    # without answering spins, whatever the host.)
    slices = HANG_CAP_FACTOR * int(TIMEOUT_S / SLICE_S)
    starved = [ProcessActivity(0.001 * k, sleeping=False) for k in range(slices + 1)]
    guard, checks = scripted(starved)
    with pytest.raises(HostStarvedError, match="the host is starved, not a firmware verdict"):
        for verdict in checks:
            assert verdict is None
    assert guard.waited_s == pytest.approx(HANG_CAP_FACTOR * TIMEOUT_S)


def test_a_starved_host_that_recovers_ends_no_wait() -> None:
    starved = [ProcessActivity(0.001 * k, sleeping=False) for k in range(40)]
    assert verdicts(starved) == [None] * 39


def test_process_activity_of_this_process() -> None:
    before = process_activity(os.getpid())
    assert before is not None
    assert before.sleeping is False  # this thread is running: it is reading the file
    sum(range(2_000_000))
    after = process_activity(os.getpid())
    assert after is not None and after.cpu_s >= before.cpu_s


def test_process_activity_of_no_process_is_none() -> None:
    assert process_activity(2**22 + 1) is None  # above the kernel's pid_max limit


def test_thread_activity_of_this_thread_and_of_a_sleeping_one() -> None:
    running = thread_activity(threading.get_native_id())
    assert running is not None and running.sleeping is False  # this thread reads the file
    started, release = threading.Event(), threading.Event()
    native_ids: list[int] = []

    def wait() -> None:
        native_ids.append(threading.get_native_id())
        started.set()
        release.wait()

    sleeper = threading.Thread(target=wait)
    sleeper.start()
    try:
        started.wait()
        asleep = None
        while asleep is None or not asleep.sleeping:  # until it is blocked in release.wait()
            asleep = thread_activity(native_ids[0])
            assert asleep is not None
    finally:
        release.set()
        sleeper.join()
    # join() returns once the thread's Python part has finished; the kernel task exits a moment
    # later (seen as state R after join on a busy host). Gone with its thread, then: the loop
    # ends when the task does (a thread that never went would hit the test's timeout).
    while thread_activity(native_ids[0]) is not None:
        os.sched_yield()


@pytest.mark.parametrize(("state", "expected"), [("S", True), ("R", False), ("Z", None), ("X", None)])
def test_an_exited_task_whose_entry_lingers_counts_as_gone(
    tmp_path: Path, state: str, expected: bool | None
) -> None:
    """A zombie or dead task (a joined thread's entry for a moment, an unreaped process) has no
    activity: None, as when its /proc entry is already gone."""
    stat = tmp_path / "stat"
    stat.write_text(f"4242 (a (name) with) {state} 1 1 1 0 -1 4194560 0 0 0 0 7 3 0 0 20 0 1 0 0\n")
    activity = _stat_activity(str(stat))
    assert (activity if activity is None else activity.sleeping) == expected
