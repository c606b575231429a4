"""The bare-metal image (firmware/platform/qemu-virt, `make baremetal`: the demo joint for qemu's
Arm `virt` machine on a CTU CAN FD controller) beside the Linux firmware on one private bus.

The scenarios marked firmware_platforms("linux", "qemu-virt") elsewhere run on both platforms
and must give the same verdicts; here the two builds are compared directly: a seeded run's every
series field by field, and a robot with modules of both platforms on one bus."""

from __future__ import annotations

import functools

import pytest
from test_determinism import differing, record_run
from test_robot import GAIT, SETTLE_S, TRACKING_TOLERANCE_RAD, tracking_error

from hilrig.session import baremetal

pytestmark = pytest.mark.bus

IDENTICAL_EXCEPT: set[str] = set()
"""The series in which the two builds may differ, each with its reason (none: they agree bit for
bit, though one is x86-64 with glibc's libm and the other a Cortex-A15 with newlib's: the
firmware is built ISO C++ (-std=c++20), where GCC contracts no a*b+c into a fused multiply-add,
so both do the same IEEE single-precision operations in the same order)."""


def test_a_seeded_run_on_the_bare_metal_image_gives_the_linux_firmwares_series_field_by_field(
    make_scenario,
) -> None:
    linux = record_run(
        functools.partial(make_scenario, firmware_platform=baremetal.LINUX), seed=7, subdir=baremetal.LINUX
    )
    virt = record_run(
        functools.partial(make_scenario, firmware_platform=baremetal.QEMU_VIRT),
        seed=7,
        subdir=baremetal.QEMU_VIRT,
    )
    assert len(virt["tpdo:motor_duty"][0]) == 250
    assert virt["tpdo:watchdog_tripped"][1].max() == 1.0, "expected the watchdog to trip on the image too"
    differ = set(differing(linux, virt))
    assert differ == IDENTICAL_EXCEPT, f"series that differ between the platforms: {sorted(differ)}"
    print(f"\n{len(linux)} series, Linux firmware and bare-metal image: {len(differ)} differ")


@pytest.mark.xdist_group("robot")
def test_a_robot_with_a_module_of_each_platform_tracks_the_gait(make_robot, scenario_dir) -> None:
    session = make_robot(2, module_platforms={2: baremetal.QEMU_VIRT})
    robot = session.robot
    GAIT.drive(robot)
    robot.run(seconds=SETTLE_S + 0.3)
    errors = {node_id: tracking_error(robot, node_id, SETTLE_S) for node_id in robot.node_ids}
    print(
        "\nlinux node 1, qemu-virt node 2: " + ", ".join(f"node {n}: {e:.4f} rad" for n, e in errors.items())
    )
    for node_id, error in errors.items():
        assert error <= TRACKING_TOLERANCE_RAD, f"node {node_id} tracks within {error:.3f} rad"
    session.close()
    assert "hilfw: qemu-virt" in (scenario_dir / "firmware-2.log").read_text()
    assert "hilfw: qemu-virt" not in (scenario_dir / "firmware-1.log").read_text()
