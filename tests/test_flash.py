"""Program download (CiA 302-3) on the Linux target: a second build of the firmware (the same
executable stamped with another 0x100A version, build/release/images/joint-firmware-second.img) flashed
into one module of a running robot comes back with the new version, in the same process (it
re-executed itself), while the other module runs on untouched; a wrong image and a broken-off
download both leave the old image running and answering with its old version.

In lockstep the rig is the robot's clock: the download happens between two runs of the robot,
so "runs on" is judged by what a module's process and cycles show across it (same process, no
boot-up, every cycle before and after answered)."""

from __future__ import annotations

import zlib
from pathlib import Path

import pytest
from conftest import REPO

from boardproto.cia301 import NmtCommand, SdoAbortCode
from boardproto.cia302 import (
    FLASH_STATUS_INDEX,
    IMAGE_HEADER_BYTES,
    SOFTWARE_ID_INDEX,
    FlashError,
    ImageHeader,
    flash_error,
)
from hilrig.errors import SdoAbortError
from hilrig.table import RigTable
from hilrig.wire import program

pytestmark = pytest.mark.bus

TABLE = RigTable.load()
SECOND_IMAGE = REPO / "build" / "release" / "images" / "joint-firmware-second.img"
FLASHED, UNTOUCHED = 2, 1


class BrokenOff(Exception):
    """The link to the board went away mid-transfer (raised from the progress callback)."""


def second_image() -> tuple[ImageHeader, bytes]:
    if not SECOND_IMAGE.exists():
        pytest.fail(f"{SECOND_IMAGE} missing: run `make build` first", pytrace=False)
    image = SECOND_IMAGE.read_bytes()
    return ImageHeader.unpack(image), image


def image_files(image_dir: Path) -> list[str]:
    return sorted(path.name for path in image_dir.iterdir())


@pytest.mark.requirement("FLASH_01", "SDO_05")
def test_second_build_flashed_into_one_module_comes_back_with_its_version(make_robot) -> None:
    header, image = second_image()
    old_version = TABLE.board.node.software_version
    assert header.software_version != old_version
    session = make_robot(2, trace=False)
    robot = session.robot
    robot.run(seconds=0.05)
    pids = [firmware.process.pid for firmware in robot.firmware]
    flashed = robot.module(FLASHED)
    assert program.software_version(flashed.node) == old_version

    image_dir = robot.firmware[FLASHED - 1].image_dir
    program.download(flashed.node, image)
    assert "staged.img" in image_files(image_dir)
    flashed.restart_node(lambda: program.start(flashed.node))

    assert program.software_version(flashed.node) == header.software_version
    assert program.read_u32(flashed.node, SOFTWARE_ID_INDEX) == header.payload_crc32
    assert program.read_u32(flashed.node, FLASH_STATUS_INDEX) == 0
    assert [firmware.process.pid for firmware in robot.firmware] == pids, "re-executed in place"
    assert (image_dir / "running.img").read_bytes() == image[IMAGE_HEADER_BYTES:]
    assert "staged.img" not in image_files(image_dir)
    cycle = robot.cycle
    robot.run(seconds=0.05)
    assert not robot.lost
    for node_id in robot.node_ids:
        t, _ = robot.module(node_id).history("output_position")
        last = (robot.cycle - 1) * robot.period_s
        assert t[-1] == pytest.approx(last), f"node {node_id} answers every cycle"
        answered = (t > (cycle - 0.5) * robot.period_s).sum()
        assert answered == robot.cycle - cycle, f"node {node_id}: a cycle missed after the flash"
    assert program.software_version(robot.module(UNTOUCHED).node) == old_version


@pytest.mark.requirement("FLASH_02")
def test_wrong_image_and_broken_off_download_leave_the_old_image_running(make_robot) -> None:
    header, image = second_image()
    old_version = TABLE.board.node.software_version
    session = make_robot(1, trace=False)
    robot = session.robot
    module = robot.module(1)
    image_dir = robot.firmware[0].image_dir
    pid = robot.firmware[0].process.pid

    # Another product's image: refused as soon as its header is in.
    payload = image[IMAGE_HEADER_BYTES : IMAGE_HEADER_BYTES + 4096]
    foreign = ImageHeader(header.product_code ^ 0xFF, "9.9.9", len(payload), zlib.crc32(payload))
    with pytest.raises(SdoAbortError) as refused:
        program.download(module.node, foreign.pack() + payload)
    assert refused.value.abort_code == SdoAbortCode.DATA_CANNOT_BE_STORED
    assert flash_error(program.read_u32(module.node, FLASH_STATUS_INDEX)) == FlashError.WRONG_BOARD

    # The right image, cut off after a tenth: the client aborts, the board discards it.
    def cut(sent: int, total: int) -> None:
        if sent >= total // 10:
            raise BrokenOff

    with pytest.raises(BrokenOff):
        program.download(module.node, image, progress=cut)
    assert flash_error(program.read_u32(module.node, FLASH_STATUS_INDEX)) == FlashError.TRANSFER_BROKEN_OFF
    assert not [name for name in image_files(image_dir) if name.startswith("staged")]
    program.start(module.node)  # nothing staged: the stopped program runs on, no restart
    assert program.software_version(module.node) == old_version
    assert robot.firmware[0].process.pid == pid
    module.nmt(NmtCommand.START)  # stop left it pre-operational; the robot runs on with it
    robot.run(seconds=0.02)
    assert not robot.lost
