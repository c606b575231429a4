"""The firmware as a bare-metal image under qemu: the platforms a session can start the board's
firmware on, and the qemu command line of the `qemu-virt` one.

    qemu_argv(image, "vcan0", node_id=16, period_us=None, mode="lockstep", flash=params.pflash)

`qemu-virt` (firmware/platform/qemu-virt, `make baremetal`): the demo joint built for a
Cortex-A15 on qemu's 32-bit Arm `virt` machine, with qemu's CTU CAN FD PCI controller
(`ctucan_pci`) joined to the bus's SocketCAN interface (`can-host-socketcan`), its boot
parameters (the Linux firmware's --node-id, --mode, --period-us) in the fw_cfg file
opt/hil/boot, its stored parameters and LSS id in the machine's second pflash, backed by a file
of FLASH_BYTES (a sparse file: qemu's flash model erases to ones and programs words as given,
so a record's magic word is what makes it, whatever the blank file held).
The image's UART is qemu's stdout (the firmware log); a guest fault prints its reason there and
ends qemu with status 1, which `Firmware.check()` reports with the log's last lines.
"""

from __future__ import annotations

import re
import shutil
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from hilrig import resources
from hilrig.errors import FirmwareError

LINUX = "linux"
QEMU_VIRT = "qemu-virt"
FIRMWARE_PLATFORMS = (LINUX, QEMU_VIRT)
"""What --firmware-platform takes: the Linux process on SocketCAN (the default), or the
bare-metal image under qemu-system-arm."""

QEMU = "qemu-system-arm"
FLASH_BYTES = 64 * 1024 * 1024
"""The virt machine's pflash size, which qemu wants its backing file to have exactly."""
BOOT_FILE = "opt/hil/boot"
"""The fw_cfg file the image reads its boot parameters from (FirmwareMain.cpp)."""


def check_platform(platform: str) -> str:
    if platform not in FIRMWARE_PLATFORMS:
        raise ValueError(
            f"firmware platform: expected one of {', '.join(FIRMWARE_PLATFORMS)}, got {platform!r}"
        )
    return platform


def default_image(platform: str) -> Path:
    """The demo joint's firmware for `platform` (the Linux one: resources.DEFAULT_FIRMWARE)."""
    return resources.VIRT_IMAGE if check_platform(platform) == QEMU_VIRT else resources.DEFAULT_FIRMWARE


def flash_file(params_file: Path) -> Path:
    """The pflash backing beside a session's parameter file (its format is the image's, not
    the Linux firmware's, so it has a name of its own)."""
    return params_file.with_name(params_file.name + ".pflash")


def prepare_flash(path: Path) -> None:
    """The flash's backing file at FLASH_BYTES, created empty (sparse) if missing; kept as it is
    otherwise, so the parameters outlive a restart of qemu."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("ab") as file:
        if file.tell() != FLASH_BYTES:
            file.truncate(FLASH_BYTES)


def serial_number(channel: str | None, node_id: int, flash: Path | None) -> int:
    """0x1018:4 of the image, as the Linux firmware derives its own: stable for one board (the
    same flash file, or the same bus and node id), different between boards."""
    seed = str(flash.resolve()) if flash is not None else f"{channel}:{node_id}"
    return zlib.crc32(seed.encode())


def qemu_argv(
    image: Path,
    channel: str | None,
    *,
    node_id: int,
    period_us: int | None,
    mode: str = "lockstep",
    flash: Path | None = None,
    extra_args: Sequence[str] = (),
    boot_extra: Sequence[str] = (),
    icount: bool = False,
    qemu: str = QEMU,
) -> list[str]:
    """qemu's command line that runs `image` on the SocketCAN interface `channel` (None: on a
    qemu bus of its own, joined to nothing), the options the Linux firmware takes as the image's
    boot parameters. `extra_args`: none is understood (the Linux firmware's fault-injection
    options have no bare-metal counterpart yet). `boot_extra`: more boot parameter words
    (count-cycles=N: the bench's cycle cost). `icount`: one instruction a nanosecond of virtual
    time (-icount shift=0), so the generic timer counts instructions."""
    if extra_args:
        raise FirmwareError(
            f"{QEMU_VIRT}: the bare-metal image takes no firmware options ({' '.join(extra_args)} are the "
            f"Linux firmware's): run this scenario with --firmware-platform {LINUX}"
        )
    serial = serial_number(channel, node_id, flash)
    words = [f"node-id={node_id}", f"mode={mode}", f"serial={serial}"]
    if period_us is not None:  # None: the image's own default (its table's [node] period_us)
        words.insert(2, f"period-us={period_us}")
    boot = " ".join([*words, f"flash={int(flash is not None)}", *boot_extra])
    argv = [
        qemu,
        "-M", "virt,highmem=off",
        "-cpu", "cortex-a15",
        "-m", "64M",
        "-nodefaults", "-display", "none", "-monitor", "none", "-no-reboot",
        "-serial", "stdio",
        "-semihosting-config", "enable=on,target=native",
        "-object", "can-bus,id=canbus0",
        *(["-object", f"can-host-socketcan,id=canhost0,if={channel},canbus=canbus0"] if channel else []),
        "-object", "can-bus,id=canbus1",  # the card's second core, on a bus of its own
        "-device", "ctucan_pci,canbus0=canbus0,canbus1=canbus1",
        "-fw_cfg", f"name={BOOT_FILE},string={boot}",
        "-kernel", str(image),
    ]  # fmt: skip
    if flash is not None:
        argv += ["-drive", f"if=pflash,index=1,format=raw,file={flash}"]
    if icount:
        argv += ["-icount", "shift=0"]
    return argv


def require_qemu(qemu: str = QEMU) -> str:
    """The qemu executable's path, or FirmwareError saying how to install it."""
    path = shutil.which(qemu)
    if path is None:
        raise FirmwareError(f"{qemu} not found: install Debian's qemu-system-arm (tools/deps does)")
    return path


_CYCLE_COST = re.compile(r"hilfw: cycle cost: cycles (\d+), ticks (\d+), worst (\d+), counter Hz (\d+)")


@dataclass(frozen=True)
class CycleCost:
    """What the image measured of its control cycles (boot parameter count-cycles=N) under
    `-icount shift=0`, where virtual time advances one nanosecond an instruction: the generic
    timer's ticks times its period in nanoseconds are instructions (to a tick's resolution)."""

    cycles: int
    instructions_per_cycle: float
    worst_instructions: int


def parse_cycle_cost(log: str) -> CycleCost:
    """The image's cycle cost line in `log`; FirmwareError when it has none."""
    match = _CYCLE_COST.search(log)
    if match is None:
        raise FirmwareError(f"no cycle cost line in the image's log: {log.strip()[-300:]!r}")
    cycles, ticks, worst, frequency = (int(group) for group in match.groups())
    ns_per_tick = 1e9 / frequency
    return CycleCost(cycles, ticks * ns_per_tick / cycles, round(worst * ns_per_tick))
