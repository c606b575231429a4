"""The generated C++ header: banner, contract names, and that it compiles with the
project's warning flags (static_asserts check the values)."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from boardproto import BoardTable
from boardproto.cpp_header import GENERATED_BANNER, cpp_float, cpp_string


@pytest.fixture(scope="module")
def header(generated_dir: Path) -> str:
    return (generated_dir / "include" / "board" / "fields.hpp").read_text()


def _enumerators(header: str, enum_name: str) -> list[str]:
    match = re.search(rf"enum class {enum_name} : std::\w+ \{{(.*?)\}};", header, re.DOTALL)
    assert match, f"enum {enum_name} not found"
    return re.findall(r"^\s+(\w+)", match.group(1), re.MULTILINE)


def test_opens_with_the_generated_banner(header: str) -> None:
    assert header.splitlines()[0] == (
        "// Generated from protocol/board.toml by protocol/boardproto. Do not edit."
    )
    assert header.startswith(GENERATED_BANNER)


def test_enums_list_the_table_in_order(header: str, table: BoardTable) -> None:
    assert _enumerators(header, "FieldId") == [*table.field_names, "kCount"]
    assert _enumerators(header, "HilInputId") == [
        *(io.name for io in table.hil_inputs),
        "kCount",
    ]
    assert _enumerators(header, "HilOutputId") == [
        *(io.name for io in table.hil_outputs),
        "kCount",
    ]


def test_declares_the_contract_api(header: str) -> None:
    for declaration in (
        "namespace board {",
        "inline constexpr std::size_t kFieldCount",
        "enum class Kind : std::uint8_t { Sensor, VirtualSensor, Module, Actuator, Command, Parameter };",
        "enum class Access : std::uint8_t { ReadOnly, ReadWrite };",
        "Real32 = 0x0008",
        "inline constexpr std::array<FieldInfo, kFieldCount> kFields",
        "constexpr const FieldInfo& info(FieldId id)",
        "inline constexpr std::array<IoInfo, kHilInputCount> kHilInputs",
        "inline constexpr std::array<IoInfo, kHilOutputCount> kHilOutputs",
        "inline constexpr NodeIdentity kNode",
        "inline constexpr std::size_t kRpdoCount = 4;",
        "inline constexpr std::size_t kTpdoCount = 8;",
        "inline constexpr std::array<PdoDefault, kRpdoCount> kDefaultRpdos",
        "inline constexpr std::array<PdoDefault, kTpdoCount> kDefaultTpdos",
        '.device_name = "hil-joint-firmware"',
    ):
        assert declaration in header, declaration


def test_literals_escape_and_round() -> None:
    assert cpp_string('say "hi" \\o/') == '"say \\"hi\\" \\\\o/"'
    assert cpp_float(0.05) == "0.05f"
    assert cpp_float(-1e6) == "-1000000.0f"
    assert cpp_float(1e30) == "1e+30f"


COMPILE_CHECK = """
#include "board/fields.hpp"
using namespace board;
static_assert(kFieldCount == {field_count});
static_assert(info(FieldId::motor_velocity).index == 0x2100);
static_assert(info(FieldId::motor_velocity).unit == "rad/s");
static_assert(info(FieldId::velocity_kp).default_value == 0.1f);
static_assert(info(FieldId::velocity_kp).kind == Kind::Parameter);
static_assert(info(FieldId::velocity_kp).stored);
static_assert(info(FieldId::joint_torque).access == Access::ReadOnly);
static_assert(kHilInputs[static_cast<std::size_t>(HilInputId::motor_current_adc)].type
              == DataType::Integer16);
static_assert(kHilOutputs[static_cast<std::size_t>(HilOutputId::led_pattern)].max == 3);
static_assert(kNode.default_node_id == 0x10 && kNode.heartbeat_ms == 100);
static_assert(kDefaultTpdos[0].cob_id_base == 0x180 && kDefaultTpdos[0].count == 2);
static_assert(kDefaultTpdos[0].entries[0].index == 0x3100);
static_assert(kDefaultTpdos[0].entries[0].bits == 16);
static_assert(!kDefaultRpdos[3].enabled && kDefaultRpdos[3].count == 0);
static_assert(static_cast<std::uint16_t>(DataType::Unsigned16) == 0x0006);
int main() {{ return 0; }}
"""


@pytest.mark.skipif(shutil.which("g++") is None, reason="needs g++")
def test_compiles_with_project_warnings(generated_dir: Path, table: BoardTable, tmp_path: Path) -> None:
    source = tmp_path / "check.cpp"
    source.write_text(COMPILE_CHECK.format(field_count=len(table.fields)))
    flags = "-std=c++20 -Wall -Wextra -Wpedantic -Wshadow -Wconversion -Werror -fsyntax-only"
    result = subprocess.run(
        ["g++", *flags.split(), f"-I{generated_dir / 'include'}", str(source)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 0, result.stderr
