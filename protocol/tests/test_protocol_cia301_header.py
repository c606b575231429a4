"""The generated `board/cia301.hpp`: every CiA 301 rule of `boardproto.cia301` is in it with the
same value (abort codes with their texts, the connection set, NMT states and commands, node-id
limits, the EMCY layout), it says it is generated, and it compiles with the project's flags."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest
from header_check import compile_header_check

from boardproto import cia301
from boardproto.cia301_header import GENERATED_BANNER, cpp_name, generate_cia301_header
from boardproto.cpp_header import cpp_string


@pytest.fixture(scope="module")
def header(generated_dir: Path) -> str:
    return (generated_dir / "include" / "board" / "cia301.hpp").read_text()


def _enum_body(header: str, name: str) -> str:
    match = re.search(rf"enum class {name} : std::\w+ \{{(.*?)\}};", header, re.DOTALL)
    assert match, f"enum class {name} not found"
    return match.group(1)


def _enumerators(header: str, name: str) -> dict[str, int]:
    """name -> value of a generated enum (C++ digit separators removed)."""
    return {
        enumerator: int(value.replace("'", ""), 16)
        for enumerator, value in re.findall(r"^\s+(\w+) = (0x[0-9A-F']+),", _enum_body(header, name), re.M)
    }


def test_the_generate_command_writes_it_with_the_banner(header: str) -> None:
    assert header.startswith(GENERATED_BANNER + "\n")
    assert "Do not edit" in header.splitlines()[0]
    assert header == generate_cia301_header()


def test_every_abort_code_is_an_enumerator_with_its_code(header: str) -> None:
    expected = {cpp_name(code): int(code) for code in cia301.SdoAbortCode}
    assert _enumerators(header, "SdoAbort") == {"None": 0, **expected}


def test_every_abort_code_is_listed_with_its_text(header: str) -> None:
    listed = re.findall(r"^\s+\{SdoAbort::(\w+), (\".*\")\},$", header, re.M)
    assert listed == [(cpp_name(code), cpp_string(code.text)) for code in cia301.SdoAbortCode]
    assert f"std::array<SdoAbortInfo, {len(cia301.SdoAbortCode)}> kSdoAborts" in header


def test_the_codes_the_firmware_lacked_before_are_there(header: str) -> None:
    enumerators = _enumerators(header, "SdoAbort")
    assert enumerators["ResourceNotAvailable"] == cia301.SdoAbortCode.RESOURCE_NOT_AVAILABLE
    assert enumerators["LocalControl"] == cia301.SdoAbortCode.LOCAL_CONTROL


def test_the_connection_set_and_nmt_enums_match(header: str) -> None:
    for python_enum in (cia301.FunctionCode, cia301.NmtState, cia301.NmtCommand):
        expected = {cpp_name(member): int(member) for member in python_enum}
        assert _enumerators(header, python_enum.__name__) == expected, python_enum.__name__


def _value_asserts() -> str:
    """static_asserts of every generated constant against the Python value."""
    layout = cia301.EmcyLayout
    checks = [
        ("kNmtCobId", cia301.NMT_COB_ID),
        ("kSyncCobId", cia301.SYNC_COB_ID),
        ("kTimeCobId", cia301.TIME_COB_ID),
        ("kStandardIdMask", cia301.STANDARD_ID_MASK),
        ("kFunctionCodeMask", cia301.FUNCTION_CODE_MASK),
        ("kNodeIdMask", cia301.NODE_ID_MASK),
        ("kPdoExtensionOffset", cia301.PDO_EXTENSION_OFFSET),
        ("kMinNodeId", cia301.MIN_NODE_ID),
        ("kMaxNodeId", cia301.MAX_NODE_ID),
        ("kNmtAllNodes", cia301.NMT_ALL_NODES),
        ("kHeartbeatStateMask", cia301.HEARTBEAT_STATE_MASK),
        ("kHeartbeatConsumerIndex", cia301.HEARTBEAT_CONSUMER_INDEX),
        ("kSyncCounterMax", cia301.SYNC_COUNTER_MAX),
        ("kLastSynchronousType", cia301.LAST_SYNCHRONOUS_TYPE),
        ("kEmcyErrorReset", cia301.EMCY_ERROR_RESET),
        ("emcy_layout::kFrameBytes", layout.FRAME_BYTES),
        ("emcy_layout::kErrorCodeOffset", layout.ERROR_CODE_OFFSET),
        ("emcy_layout::kErrorCodeBytes", layout.ERROR_CODE_BYTES),
        ("emcy_layout::kErrorRegisterOffset", layout.ERROR_REGISTER_OFFSET),
        ("emcy_layout::kManufacturerOffset", layout.MANUFACTURER_OFFSET),
        ("emcy_layout::kManufacturerBytes", layout.MANUFACTURER_BYTES),
    ]
    lines = [f"static_assert({name} == {value});" for name, value in checks]
    lines += [
        f"static_assert(text(SdoAbort::{cpp_name(code)}) == {cpp_string(code.text)});"
        for code in cia301.SdoAbortCode
    ]
    lines.append("static_assert(text(SdoAbort::None).empty());")
    lines += [
        f"static_assert(cob_id(FunctionCode::{cpp_name(f)}, 0x10) == 0x{cia301.cob_id(f, 0x10):X});"
        for f in cia301.FunctionCode
    ]
    for can_id in range(cia301.STANDARD_ID_MASK + 1):
        if cia301.is_restricted_cob_id(can_id) != cia301.is_restricted_cob_id(can_id - 1):
            restricted = "true" if cia301.is_restricted_cob_id(can_id) else "false"
            lines.append(f"static_assert(is_restricted_cob_id(0x{can_id:03X}) == {restricted});")
    for node_id in (0, cia301.MIN_NODE_ID, cia301.MAX_NODE_ID, cia301.MAX_NODE_ID + 1):
        valid = "true" if cia301.is_node_id(node_id) else "false"
        lines.append(f"static_assert(is_node_id({node_id}) == {valid});")
    return "\n".join(lines)


@pytest.mark.skipif(shutil.which("g++") is None, reason="needs g++")
def test_compiles_to_the_python_values(generated_dir: Path, tmp_path: Path) -> None:
    result = compile_header_check(generated_dir, tmp_path, "cia301.hpp", "cia301", _value_asserts())
    assert result.returncode == 0, result.stderr


def test_abort_codes_are_unique_and_in_order() -> None:
    codes = [int(code) for code in cia301.SdoAbortCode]
    assert codes == sorted(set(codes))
    assert all(code.text and code.text == code.text.strip() for code in cia301.SdoAbortCode)
