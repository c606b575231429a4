"""The bench's image size (`hilrig.apps.bench.size`): the Cortex-M firmware image's flash and RAM
rows, read from the image's linker symbols, and the goal MISSED when a figure is over its
budget."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from hilrig.apps.bench import common as bench_common
from hilrig.apps.bench import report as bench_report
from hilrig.apps.bench import size as bench_size

NM_LISTING = """\
00020000 A __flash_budget
0001c000 B __flash_used
0001c000 A __ram_budget
0001e000 A __ram_used
00000000 T Reset_Handler
"""


def image_listing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, listing: str) -> Path:
    """An image file whose `arm-none-eabi-nm` listing is `listing`."""
    image = tmp_path / "joint-firmware.elf"
    image.write_bytes(b"")

    def run(command: list[str], **kwargs: object) -> subprocess.CompletedProcess[str]:
        return subprocess.CompletedProcess(command, 0, listing, "")

    monkeypatch.setattr(bench_size.subprocess, "run", run)
    return image


def test_rows_compare_each_memory_with_its_budget_and_flag_the_one_over_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    size = bench_size.image_size(image_listing(tmp_path, monkeypatch, NM_LISTING))
    assert (size["flash_bytes"], size["flash_budget"]) == (0x1C000, 0x20000)
    rows = bench_report.ReportRows()
    bench_size.size_rows(rows, size)
    flash, ram = rows
    assert (flash["ours"], flash["baseline"], flash["goal_met"]) == ("112.0 KiB", "128 KiB budget", True)
    assert flash["ratio"] == pytest.approx(0.875)
    assert (ram["ours"], ram["baseline"], ram["goal_met"]) == ("120.0 KiB", "112 KiB budget", False)
    assert "MISSED" in "\n".join(bench_report.format_table(rows))


def test_an_image_not_built_is_a_probe_error_that_says_how_to_build_it(tmp_path: Path) -> None:
    with pytest.raises(bench_common.ProbeError, match="make cortex-m"):
        bench_size.image_size(tmp_path / "missing.elf")


def test_an_image_without_the_budget_symbols_is_a_probe_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    image = image_listing(tmp_path, monkeypatch, "00000000 T Reset_Handler\n")
    with pytest.raises(bench_common.ProbeError, match="__flash_used"):
        bench_size.image_size(image)
