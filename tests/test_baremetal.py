"""The bare-metal image (firmware/platform/qemu-virt, `make baremetal`: the demo joint for qemu's
Arm `virt` machine on a CTU CAN FD controller) beside the Linux firmware on one private bus.

The scenarios marked firmware_platforms("linux", "qemu-virt") elsewhere run on both platforms
and must give the same verdicts; here the two builds are compared directly: a seeded run's every
series field by field, and a robot with modules of both platforms on one bus."""

from __future__ import annotations

import functools
import re
import shutil
import subprocess

import numpy as np
import pytest
from conftest import FULL_MAPPING_ON_THE_IDEAL_BUS
from test_determinism import differing, record_run
from test_robot import GAIT, SETTLE_S, TRACKING_TOLERANCE_RAD, tracking_error

from hilrig import resources
from hilrig.session import baremetal

pytestmark = [pytest.mark.bus, FULL_MAPPING_ON_THE_IDEAL_BUS]

FUSED = {
    "_ZN5joint14VelocityFilter6updateEfff": {"tpdo:motor_velocity", "tpdo:output_velocity"},
    "_ZN5joint13PidController6updateEfffRKNS_8PidGainsEf": {
        "tpdo:velocity_controller_output",
        "tpdo:motor_duty_command",
    },
    "_ZN5joint17SpringConstantRls6updateEdd": set(),  # the estimate is not in this run's TPDOs
    "_ZNK5joint17SpringConstantRls10confidenceEv": set(),
    # The CiA 402 drive's modes and position scaling: no 402 mode is selected in this run.
    "_ZN5joint11Cia402Drive8run_modeEtbff": set(),
    "_ZNK5joint11Cia402Drive19mrad_to_gearbox_radEf": set(),
}
"""The one difference between the builds: floating-point contraction. GCC contracts a*b+c into a
fused multiply-add by default in C++ (-ffp-contract=fast; only ISO C turns it off), the
Cortex-A15's VFPv4 has one (vfma), x86-64's baseline has none: in these functions of the image
the product is not rounded before the sum, so their results, and what is computed from them,
differ in the last bits. Each function with the series it moves. The image built with
-ffp-contract=off gave all 34 series bit for bit equal (checked when this was written); newlib's
expf and logf fuse too, inside, but they round the same as glibc's (no series they feed differs)."""
LIBM = {"expf", "logf"}
RELATIVE_DIFFERENCE = 1e-6
"""How far a contracted series may stray, relative to its largest magnitude: a few float ULPs
(measured: under 1e-7 for each)."""
CONTRACTED = set().union(*FUSED.values())


def test_the_images_fused_multiply_adds_are_in_the_functions_named_and_libm_only() -> None:
    objdump = shutil.which("arm-none-eabi-objdump")
    image = resources.VIRT_IMAGE
    if objdump is None or not image.exists():
        pytest.fail(f"needs arm-none-eabi-objdump and {image} (make baremetal)", pytrace=False)
    listing = subprocess.run(
        [objdump, "-d", "--no-show-raw-insn", str(image)], capture_output=True, text=True, check=True
    )
    fused: set[str] = set()
    function = ""
    for line in listing.stdout.splitlines():
        if header := re.match(r"^[0-9a-f]+ <(.+)>:$", line):
            function = header.group(1)
        elif re.search(r"\bv(fma|fms|fnma|fnms)\.f(32|64)\b", line):
            fused.add(function)
    assert fused == set(FUSED) | LIBM, f"functions with a fused multiply-add: {sorted(fused)}"


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
    assert differ == CONTRACTED, f"series that differ between the platforms: {sorted(differ)}"
    worst = {}
    for name in sorted(differ):
        (t_linux, v_linux), (t_virt, v_virt) = linux[name], virt[name]
        assert np.array_equal(t_linux, t_virt), f"{name}: the same cycles"
        worst[name] = float(np.max(np.abs(v_linux - v_virt)) / max(float(np.max(np.abs(v_linux))), 1e-30))
        assert worst[name] <= RELATIVE_DIFFERENCE, f"{name}: {worst[name]:.2e} of its range"
    print(
        f"\n{len(linux)} series, Linux firmware and bare-metal image: {len(linux) - len(differ)} bit for bit "
        "equal; contracted, relative to their range: " + ", ".join(f"{n} {w:.1e}" for n, w in worst.items())
    )


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
