"""The generated `board/cia305.hpp`: every LSS rule of `boardproto.cia305` is in it with the same
value (COB-IDs, command specifiers, states, error codes, fastscan values, the bit timing table),
it says it is generated, and it compiles with the project's flags."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from header_check import compile_header_check

from boardproto import cia305
from boardproto.cia301_header import cpp_name
from boardproto.cia305_header import GENERATED_BANNER, generate_cia305_header


def test_the_generate_command_writes_it_with_the_banner(generated_dir: Path) -> None:
    header = (generated_dir / "include" / "board" / "cia305.hpp").read_text()
    assert header.startswith(GENERATED_BANNER + "\n")
    assert header == generate_cia305_header()


def _value_asserts() -> str:
    checks = [
        ("kMasterCobId", cia305.MASTER_COB_ID),
        ("kSlaveCobId", cia305.SLAVE_COB_ID),
        ("kFrameBytes", cia305.FRAME_BYTES),
        ("kNodeIdUnconfigured", cia305.NODE_ID_UNCONFIGURED),
        ("kFastscanConfirm", cia305.FASTSCAN_CONFIRM),
        ("kFastscanHighestBit", cia305.FASTSCAN_HIGHEST_BIT),
        ("kIdentityParts", cia305.IDENTITY_PARTS),
        ("kBitTimingStandardTable", cia305.BIT_TIMING_STANDARD_TABLE),
    ]
    lines = [f"static_assert({name} == {value});" for name, value in checks]
    for python_enum in (cia305.LssState, cia305.LssCommand, cia305.LssError):
        lines += [
            f"static_assert(static_cast<int>({python_enum.__name__}::{cpp_name(m)}) == {int(m)});"
            for m in python_enum
        ]
    for index in range(16):
        lines.append(f"static_assert(bit_timing_kbits({index}) == {cia305.BIT_TIMING_KBITS.get(index, 0)});")
    return "\n".join(lines)


@pytest.mark.skipif(shutil.which("g++") is None, reason="needs g++")
def test_compiles_to_the_python_values(generated_dir: Path, tmp_path: Path) -> None:
    result = compile_header_check(generated_dir, tmp_path, "cia305.hpp", "cia305", _value_asserts())
    assert result.returncode == 0, result.stderr


def test_the_fastscan_frame_has_the_spec_layout() -> None:
    frame = cia305.fastscan_frame(0x12345678, 31, 3, 0)
    assert frame == bytes([0x51, 0x78, 0x56, 0x34, 0x12, 31, 3, 0])
    assert cia305.command_frame(cia305.LssCommand.CONFIGURE_NODE_ID, 5) == bytes([0x11, 5, 0, 0, 0, 0, 0, 0])
    selective = cia305.u32_frame(cia305.LssCommand.SWITCH_STATE_SELECTIVE_SERIAL, 1)
    assert selective == bytes([0x43, 1, 0, 0, 0, 0, 0, 0])
