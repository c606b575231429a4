"""The bare-metal image's launcher (hilrig.session.baremetal): qemu's command line, and the
image itself under qemu natively (no CAN interface needed: a qemu bus of its own), where it
reports its guest faults and its cycle cost; qemu's own exit reaches `Firmware.check()`."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path
from typing import Any

import pytest

from hilrig import resources
from hilrig.errors import FirmwareError
from hilrig.session import baremetal
from hilrig.session.firmware import Firmware

IMAGE = resources.VIRT_IMAGE
needs_image = pytest.mark.skipif(
    shutil.which(baremetal.QEMU) is None or not IMAGE.exists(),
    reason=f"needs {baremetal.QEMU} and {IMAGE} (`make baremetal`)",
)


class DirectLauncher:
    """Starts the command as given, on an interface name no kernel here has."""

    channel = "hilnosuchcan0"

    def popen(self, argv: list[str], **kwargs: Any) -> subprocess.Popen[Any]:
        return subprocess.Popen(argv, **kwargs)


def test_the_command_line_says_what_the_linux_firmwares_options_say(tmp_path: Path) -> None:
    flash = tmp_path / "params.bin.pflash"
    argv = baremetal.qemu_argv(IMAGE, "vcan0", node_id=0x21, period_us=500, mode="free", flash=flash)
    boot = next(arg for arg in argv if arg.startswith(f"name={baremetal.BOOT_FILE},string="))
    assert boot.split("string=", 1)[1].split() == [
        "node-id=33",
        "mode=free",
        "period-us=500",
        f"serial={baremetal.serial_number('vcan0', 0x21, flash)}",
        "flash=1",
    ]
    assert "can-host-socketcan,id=canhost0,if=vcan0,canbus=canbus0" in argv
    assert argv[argv.index("-drive") + 1] == f"if=pflash,index=1,format=raw,file={flash}"
    assert argv[argv.index("-kernel") + 1] == str(IMAGE)
    alone = baremetal.qemu_argv(IMAGE, None, node_id=1, period_us=1000, icount=True)
    assert not any("can-host-socketcan" in arg for arg in alone) and "-drive" not in alone
    assert alone[-2:] == ["-icount", "shift=0"]


def test_the_linux_firmwares_own_options_are_refused_with_what_to_do() -> None:
    with pytest.raises(FirmwareError, match="--firmware-platform linux"):
        baremetal.qemu_argv(
            IMAGE, "vcan0", node_id=1, period_us=1000, extra_args=["--inject-rogue-write-at-cycle", "5"]
        )
    with pytest.raises(ValueError, match="expected one of linux, qemu-virt"):
        baremetal.check_platform("stm32")


def test_the_flash_file_has_the_machines_size_and_keeps_what_it_holds(tmp_path: Path) -> None:
    flash = baremetal.flash_file(tmp_path / "params.bin")
    baremetal.prepare_flash(flash)
    assert flash.stat().st_size == baremetal.FLASH_BYTES
    with flash.open("r+b") as file:
        file.write(b"PLIH")
    baremetal.prepare_flash(flash)
    assert flash.read_bytes()[:4] == b"PLIH"


@needs_image
def test_a_guest_fault_ends_qemu_with_status_1_and_its_reason_in_the_log(tmp_path: Path) -> None:
    argv = baremetal.qemu_argv(IMAGE, None, node_id=1, period_us=1000, boot_extra=["no-such-word=1"])
    done = subprocess.run(argv, capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 1, done
    assert "hilfw: bad boot parameter: no-such-word=1" in done.stdout
    assert "hilfw: fault: boot parameters" in done.stdout


@needs_image
def test_the_image_counts_its_cycles_instructions_under_icount() -> None:
    argv = baremetal.qemu_argv(
        IMAGE, None, node_id=1, period_us=1000, mode="free", boot_extra=["count-cycles=200"], icount=True
    )
    done = subprocess.run(argv, capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done
    cost = baremetal.parse_cycle_cost(done.stdout)
    assert cost.cycles == 200
    assert 100 < cost.instructions_per_cycle < 100_000, cost
    assert cost.worst_instructions >= cost.instructions_per_cycle


@needs_image
def test_qemu_that_cannot_start_is_reported_with_the_last_lines_of_its_log(tmp_path: Path) -> None:
    firmware = Firmware(
        DirectLauncher(),
        node_id=1,
        log_path=tmp_path / "fw.log",
        executable=IMAGE,
        platform=baremetal.QEMU_VIRT,
    )
    firmware.start()
    assert firmware.process is not None
    firmware.process.wait(60)
    with pytest.raises(FirmwareError, match=r"exited with code 1; last lines of .*\nqemu-system-arm: "):
        firmware.check()
    firmware.stop()
