"""[[array]]: an ARRAY object of board fields at one index (CiA 402's 0x607D software position
limit, 0x6099 homing speeds), in the table, the EDS canopen imports, and the C++ header."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import canopen
import pytest
from canopen.objectdictionary import INTEGER32, UNSIGNED8, UNSIGNED32, ODArray

from boardproto import BoardTable, TableError, load_table
from boardproto.cpp_header import generate_header
from boardproto.eds import generate_eds

TableWriter = Callable[[str], Path]

# Two INTEGER32 members of an array at 0x607D, appended to the minimal table.
ARRAY = """
[[array]]
name = "software_position_limit"
index = 0x607D
description = "Limits"

[[field]]
name = "min_position_limit"
index = 0x607D
subindex = 1
type = "integer32"
unit = "mrad"
kind = "parameter"
min = -1000
max = 1000
default = -1000
stored = true
description = "Low"

[[field]]
name = "max_position_limit"
index = 0x607D
subindex = 2
type = "integer32"
unit = "mrad"
kind = "parameter"
min = -1000
max = 1000
default = 1000
stored = true
description = "High"
"""


def with_array(minimal_table: str, text: str = ARRAY) -> str:
    """The minimal table with `text` before its PDOs."""
    head, pdo, tail = minimal_table.partition("[pdo]")
    return head + text + "\n" + pdo + tail


def refused(path: Path, *fragments: str) -> None:
    with pytest.raises(TableError) as caught:
        load_table(path)
    message = str(caught.value)
    assert message.startswith(f"{path}: ") and "\n" not in message, message
    for fragment in fragments:
        assert fragment in message, f"expected {fragment!r} in {message!r}"


def test_the_joints_402_arrays_are_fields_by_name_and_by_sub_index(table: BoardTable) -> None:
    limits = table.array_at(0x607D)
    speeds = table.array_at(0x6099)
    assert limits is not None and limits.members == ("min_position_limit", "max_position_limit")
    assert speeds is not None and speeds.members == (
        "speed_during_search_for_switch",
        "speed_during_search_for_zero",
    )
    assert table.entry_at(0x607D, 2) is table.field("max_position_limit")
    assert table.field("speed_during_search_for_switch").subindex == 1
    assert table.array_at(0x6081) is None
    assert "0x6099 is not implemented" not in table.field("profile_velocity").description


def test_canopen_imports_each_array_with_its_count_and_typed_members(
    table: BoardTable, tmp_path: Path
) -> None:
    eds = tmp_path / "board.eds"
    eds.write_text(generate_eds(table))
    od = canopen.import_od(str(eds))
    for index, data_type, names in (
        (0x607D, INTEGER32, ("min_position_limit", "max_position_limit")),
        (0x6099, UNSIGNED32, ("speed_during_search_for_switch", "speed_during_search_for_zero")),
    ):
        array = od[index]
        assert isinstance(array, ODArray), hex(index)
        count = array[0]
        assert (count.data_type, count.access_type, count.default) == (UNSIGNED8, "ro", 2)
        for sub, name in enumerate(names, start=1):
            member = array[sub]
            field = table.field(name)
            assert (member.name, member.data_type, member.access_type) == (name, data_type, "rw")
            assert member.default == int(field.default) and (member.min, member.max) == (field.min, field.max)
            assert member.storage_location == "PERSIST"
            assert od[array.name][name] is member
    # A negative default survives the round trip (canopen's exporter writes hex otherwise).
    assert od[0x607D][1].default == -10_000_000


def test_the_header_gives_each_field_its_sub_index_and_lists_the_arrays(table: BoardTable) -> None:
    header = generate_header(table)
    assert '{.name = "software_position_limit", .index = 0x607D, .count = 2},' in header
    assert '{.name = "homing_speeds", .index = 0x6099, .count = 2},' in header
    assert '.name = "max_position_limit", .index = 0x607D, .subindex = 2,' in header
    assert '.name = "controlword", .index = 0x6040, .subindex = 0,' in header


def test_a_minimal_array_loads(minimal_table: str, write_table: TableWriter) -> None:
    table = load_table(write_table(with_array(minimal_table)))
    (array,) = table.arrays
    assert (array.name, array.index, array.count) == ("software_position_limit", 0x607D, 2)
    assert [f.subindex for f in table.fields] == [0, 0, 1, 2]


@pytest.mark.parametrize(
    ("old", "new", "fragments"),
    [
        (
            'index = 0x607D\ndescription = "Limits"',
            'index = 0x607E\ndescription = "Limits"',
            ("array 'software_position_limit'", "no [[field]] at index 0x607E"),
        ),
        ("subindex = 2", "subindex = 3", ("members must be sub-indices 1..2, got [1, 3]",)),
        ("subindex = 2", "subindex = 1", ("index 0x607D sub 1 already used by 'min_position_limit'",)),
        (
            'subindex = 2\ntype = "integer32"',
            'subindex = 2\ntype = "integer16"',
            ("members of an ARRAY share one type", "max_position_limit integer16"),
        ),
        ('name = "software_position_limit"', 'name = "velocity_kp"', ("already a field's",)),
        ("subindex = 2\n", "", ("0x607D is taken by 'max_position_limit', a plain object",)),
        ("subindex = 1", "subindex = 255", ("subindex 255 outside 0..254",)),
    ],
)
def test_refuses_an_array_that_is_not_sub_1_to_n_of_one_type(
    minimal_table: str, write_table: TableWriter, old: str, new: str, fragments: tuple[str, ...]
) -> None:
    text = with_array(minimal_table)
    assert text.count(old) == 1, f"test setup: {old!r}"
    refused(write_table(text.replace(old, new)), *fragments)


def test_refuses_an_array_with_no_members(minimal_table: str, write_table: TableWriter) -> None:
    lonely = '\n[[array]]\nname = "homing_speeds"\nindex = 0x6099\ndescription = "Speeds"\n'
    refused(write_table(with_array(minimal_table, ARRAY + lonely)), "array 'homing_speeds'", "no [[field]]")


def test_refuses_a_sub_index_outside_any_array(minimal_table: str, write_table: TableWriter) -> None:
    members = ARRAY.split("[[field]]", 1)[1]
    refused(
        write_table(with_array(minimal_table, "[[field]]" + members)),
        "field 'min_position_limit'",
        "subindex 1 needs an [[array]] at index 0x607D",
    )
