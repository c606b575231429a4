"""The generated C++ header: banner, contract names, and that it compiles with the
project's warning flags (static_asserts check the values, those of the enums, flag bits
and EMCY codes written from the Python table)."""

from __future__ import annotations

import re
import shutil
import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest

from boardproto import BoardTable, TableError, load_table
from boardproto.cli import generate
from boardproto.cpp_header import (
    GENERATED_BANNER,
    cpp_comment,
    cpp_float,
    cpp_string,
    enum_underlying_type,
    generate_header,
)
from boardproto.standard import standard_document
from boardproto.table import EnumValue, ErrorRegisterBit, ValueEnum, camel_case


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
static_assert(kNode.period_us == 1000 && kNode.period_us_min == 100 && kNode.period_us_max == 1000000);
static_assert(kNode.boot_ms == 20);
static_assert(kHeartbeatConsumers == {heartbeat_consumers});
static_assert(emcy_code::kHeartbeatError == 0x8130);
static_assert(info(EmcyId::heartbeat_error).register_bit == error_register::kCommunication);
static_assert(*kFaultFlagsInfo[static_cast<std::size_t>(FaultFlagsBit::MasterHeartbeatLost)].emcy
              == EmcyId::heartbeat_error);
static_assert(kFaultFlagsField == FieldId::fault_flags && kFaultFlagsEmcy.size() == kFaultFlagsInfo.size());
static_assert(kOwnershipViolationBit == static_cast<std::uint8_t>(FaultFlagsBit::OwnershipViolation));
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
    source.write_text(
        COMPILE_CHECK.format(
            field_count=len(table.fields), heartbeat_consumers=table.node.heartbeat_consumers
        )
    )
    flags = "-std=c++20 -Wall -Wextra -Wpedantic -Wshadow -Wconversion -Werror -fsyntax-only"
    result = subprocess.run(
        ["g++", *flags.split(), f"-I{generated_dir / 'include'}", str(source)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert result.returncode == 0, result.stderr


# ---------------------------------------------------------------------------
# [[emcy]], [[enum]] and [[bitset]]
# ---------------------------------------------------------------------------


def test_enums_and_bitsets_list_the_table(header: str, table: BoardTable) -> None:
    for values in table.enums:
        assert _enumerators(header, values.type_name) == [camel_case(v.name) for v in values.values]
        for value in values.values:
            assert f"  {camel_case(value.name)} = {value.value}," in header
    for bitset in table.bitsets:
        lowest_first = sorted(bitset.bits, key=lambda b: b.bit)
        assert _enumerators(header, f"{bitset.type_name}Bit") == [camel_case(b.name) for b in lowest_first]
    assert _enumerators(header, "EmcyId") == [*(c.name for c in table.emcy_codes), "kCount"]


def test_declares_the_value_api(header: str) -> None:
    for declaration in (
        "enum class ControlMode : std::uint8_t {",
        "inline constexpr std::array<ControlMode, 4> kControlModeValues",
        "constexpr float to_value(ControlMode value)",
        "constexpr std::string_view to_string(ControlMode value)",
        "constexpr std::optional<ControlMode> control_mode_from_value(float value)",
        "enum class LedPattern : std::uint8_t {",
        "enum class FaultFlagsBit : std::uint8_t {",
        "inline constexpr std::array<FaultFlagsBit, 7> kFaultFlagsBits",
        "inline constexpr std::uint32_t kFaultFlagsMask = 0x0000007F;",
        "constexpr std::uint32_t mask(FaultFlagsBit bit)",
        "constexpr std::string_view to_string(FaultFlagsBit bit)",
        "inline constexpr std::array<FlagInfo, 7> kFaultFlagsInfo",
        "inline constexpr std::array<EmcyInfo, kEmcyCount> kEmcyCodes",
        "constexpr const EmcyInfo& info(EmcyId id)",
        "inline constexpr std::uint8_t kGeneric = 0x01;",
        "inline constexpr std::uint8_t kManufacturer = 0x80;",
        "inline constexpr std::uint16_t kSetpointStreamLost = info(EmcyId::setpoint_stream_lost).code;",
        "constexpr void for_each_enum(Visit&& visit)",
        "constexpr void for_each_bitset(Visit&& visit)",
        "// Carried by: drive_mode (0x220A), control_mode (0x2400).",
        "// Carried by: led_pattern_command (0x2209), led_pattern (0x3101).",
    ):
        assert declaration in header, declaration


def test_error_register_constants_are_the_cia301_bits(header: str) -> None:
    for bit in ErrorRegisterBit:
        assert f"inline constexpr std::uint8_t k{camel_case(bit.toml_name)} = 0x{bit.value:02X};" in header


def test_enum_type_is_the_narrowest_that_holds_every_value() -> None:
    def values(*numbers: int) -> ValueEnum:
        return ValueEnum("v", "", tuple(EnumValue(f"v{i}", number, "") for i, number in enumerate(numbers)))

    assert enum_underlying_type(values(0, 255)) == "std::uint8_t"
    assert enum_underlying_type(values(-1, 127)) == "std::int8_t"
    assert enum_underlying_type(values(0, 256)) == "std::uint16_t"
    assert enum_underlying_type(values(-129, 0)) == "std::int16_t"
    assert enum_underlying_type(values(-(1 << 24), 1 << 24)) == "std::int32_t"


def test_comment_never_ends_in_a_line_splice() -> None:
    assert cpp_comment("a\\") == "a\\."
    assert cpp_comment("plain") == "plain"


def _value_asserts(table: BoardTable) -> str:
    """static_asserts that the header's values are the Python table's, one per value."""
    lines = []
    for values in table.enums:
        for value in values.values:
            member = f"{values.type_name}::{camel_case(value.name)}"
            lines += [
                f"static_assert(to_value({member}) == {value.value}.0f);",
                f'static_assert(to_string({member}) == "{value.name}");',
                f"static_assert({values.name}_from_value({value.value}.0f) == {member});",
            ]
        lines.append(f"static_assert(k{values.type_name}Values.size() == {len(values.values)});")
    for bitset in table.bitsets:
        for bit in bitset.bits:
            member = f"{bitset.type_name}Bit::{camel_case(bit.name)}"
            lines.append(f"static_assert(mask({member}) == 0x{bit.mask:X}u);")
            info = f"k{bitset.type_name}Info[{sorted(b.bit for b in bitset.bits).index(bit.bit)}]"
            lines.append(f'static_assert({info}.name == "{bit.name}" && {info}.bit == {bit.bit});')
            if bit.emcy is None:
                lines.append(f"static_assert(!{info}.emcy);")
            else:
                lines.append(f"static_assert({info}.emcy == EmcyId::{bit.emcy});")
            if bit.about is None:
                lines.append(f"static_assert(!{info}.about_index);")
            else:
                index = table.entry(bit.about).index
                lines.append(f"static_assert({info}.about_index == 0x{index:04X});")
    for n, code in enumerate(table.emcy_codes):
        lines += [
            f"static_assert(info(EmcyId::{code.name}).code == 0x{code.code:04X});",
            f"static_assert(info(EmcyId::{code.name}).register_bit == 0x{code.error_register.value:02X});",
            f"static_assert(static_cast<std::size_t>(EmcyId::{code.name}) == {n});",
            f"static_assert(emcy_code::k{camel_case(code.name)} == 0x{code.code:04X});",
        ]
    return "\n".join(lines)


def _compile(include_dir: Path, source_text: str, tmp_path: Path) -> subprocess.CompletedProcess[str]:
    source = tmp_path / "check.cpp"
    source.write_text(source_text)
    flags = "-std=c++20 -Wall -Wextra -Wpedantic -Wshadow -Wconversion -Werror -fsyntax-only"
    return subprocess.run(
        ["g++", *flags.split(), f"-I{include_dir}", str(source)],
        capture_output=True,
        text=True,
        check=False,
    )


@pytest.mark.skipif(shutil.which("g++") is None, reason="needs g++")
def test_values_compile_to_the_python_tables_values(
    generated_dir: Path, table: BoardTable, tmp_path: Path
) -> None:
    source = f'#include "board/fields.hpp"\nusing namespace board;\n{_value_asserts(table)}\n'
    result = _compile(generated_dir / "include", source, tmp_path)
    assert result.returncode == 0, result.stderr


# Value sets the real table does not have yet: a negative and a wide enum value, a bitset with a
# gap and a bit without EMCY, an EMCY about a HIL I/O object, a description ending in "\".
ODD_VALUE_SETS = """
[[emcy]]
name = "encoder_lost"
code = 0x7305
error_register = "device_profile"
description = "About a HIL input"

[[enum]]
name = "direction"
description = "Signed values \\\\"

[[enum.values]]
name = "reverse"
value = -1
description = "Backwards \\\\"

[[enum.values]]
name = "far_away"
value = 70000
description = "Wide"

[[bitset]]
name = "status_bits"
description = "A gap and a silent bit"

[[bitset.bits]]
name = "encoder_lost"
bit = 23
emcy = "encoder_lost"
about = "motor_encoder_counts"
description = "Highest bit a float holds"

[[bitset.bits]]
name = "warning"
bit = 2
description = "No EMCY"
"""


@pytest.mark.skipif(shutil.which("g++") is None, reason="needs g++")
def test_odd_value_sets_compile_to_their_values(
    minimal_table: str, write_table: Callable[[str], Path], tmp_path: Path
) -> None:
    odd = load_table(write_table(minimal_table + ODD_VALUE_SETS))
    generate(odd.source, tmp_path / "out")
    header = (tmp_path / "out" / "include" / "board" / "fields.hpp").read_text()
    assert "enum class Direction : std::int32_t {" in header
    assert _enumerators(header, "StatusBitsBit") == ["Warning", "EncoderLost"]
    source = f'#include "board/fields.hpp"\nusing namespace board;\n{_value_asserts(odd)}\n'
    source += "static_assert(!direction_from_value(0.0f));\n"
    result = _compile(tmp_path / "out" / "include", source, tmp_path)
    assert result.returncode == 0, result.stderr


@pytest.mark.skipif(shutil.which("g++") is None, reason="needs g++")
def test_a_table_without_value_sets_compiles_with_the_standard_ones(
    minimal_table: str, write_table: Callable[[str], Path], tmp_path: Path
) -> None:
    generate(write_table(minimal_table), tmp_path / "out")
    standard_codes = len(standard_document()["emcy"])
    source = (
        '#include "board/fields.hpp"\n'
        f"static_assert(board::kEmcyCount == {standard_codes});\n"
        "static_assert(board::kRecorder.index == board::recorder::kState);\n"
        "static_assert(board::RecorderState::Done != board::RecorderState::Idle);\n"
        "static_assert(!board::kFaultFlagsField && board::kFaultFlagsEmcy.empty());\n"
        "static_assert(!board::kOwnershipViolationBit);\n"
    )
    result = _compile(tmp_path / "out" / "include", source, tmp_path)
    assert result.returncode == 0, result.stderr


@pytest.mark.parametrize(
    ("addition", "fragments"),
    [
        (
            '[[enum]]\nname = "kind"\ndescription = "x"\n[[enum.values]]\nname = "a"\nvalue = 0\n'
            'description = "x"\n',
            ("enum 'kind'", "C++ type name Kind is already a type of the header itself"),
        ),
        (
            '[[enum]]\nname = "e"\ndescription = "x"\n[[enum.values]]\nname = "a_1b"\nvalue = 0\n'
            'description = "x"\n[[enum.values]]\nname = "a1b"\nvalue = 1\ndescription = "x"\n',
            ("enum 'e'", "'a1b' and 'a_1b' both become the C++ name A1b"),
        ),
        (
            '[[enum]]\nname = "flags_bit"\ndescription = "x"\n[[enum.values]]\nname = "a"\nvalue = 0\n'
            'description = "x"\n[[bitset]]\nname = "flags"\ndescription = "x"\n[[bitset.bits]]\n'
            'name = "a"\nbit = 0\ndescription = "x"\n',
            ("bitset 'flags'", "FlagsBit is already the type of enum 'flags_bit'"),
        ),
    ],
)
def test_refuses_names_that_collide_in_cpp(
    minimal_table: str, write_table: Callable[[str], Path], addition: str, fragments: tuple[str, ...]
) -> None:
    table = load_table(write_table(minimal_table + "\n" + addition))
    with pytest.raises(TableError) as caught:
        generate_header(table)
    for fragment in fragments:
        assert fragment in str(caught.value)
