"""hilrig's pytest plugin in a project of its own (`pytester`): the board its ini options name
(table, EDS, firmware, plant), a one-line error for a bad one, the longest scenarios first, and
nothing at all in a project that sets none of it. The scenarios on a bus use the same fixtures:
tests/ and examples/other-project."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from hilrig import resources
from hilrig.plants import default_plant

TABLE = resources.DEFAULT_TABLE

PLANT_MODULE = """
from hilrig.plants.joint import JointModel

made = []

def make_plant(params, seed):
    made.append((params, seed))
    return JointModel.of(params, seed)
"""

BOARD_TEST = """
import toy_plant
from hilrig.plants.interface import Plant

def test_board(hil_board):
    assert hil_board.table.board.node.default_node_id == 0x10
    assert hil_board.eds.name == "board.eds" and hil_board.eds.is_file()
    assert str(hil_board.firmware).endswith("bin/toy-firmware")
    assert hil_board.firmware_args == ("--verbose", "two words")
    assert hil_board.plant is toy_plant.make_plant
    assert isinstance(hil_board.plant(None, 3), Plant) and toy_plant.made == [(None, 3)]
"""


def _project(pytester: pytest.Pytester, ini: str) -> None:
    shutil.copyfile(TABLE, pytester.path / "board.toml")
    pytester.makeini("[pytest]\n" + ini)
    pytester.makepyfile(toy_plant=PLANT_MODULE)


def test_the_ini_options_name_the_board_relative_to_the_ini_file(pytester: pytest.Pytester) -> None:
    _project(
        pytester,
        "hil_table = board.toml\nhil_firmware = bin/toy-firmware\n"
        "hil_firmware_args = --verbose 'two words'\nhil_plant = toy_plant:make_plant\n",
    )
    pytester.makepyfile(test_board=BOARD_TEST)
    pytester.syspathinsert()
    pytester.runpytest("-p", "no:cacheprovider").assert_outcomes(passed=1)


def test_without_options_the_board_is_hilrigs_own(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(
        test_default="""
from hilrig import resources
from hilrig.plants import default_plant

def test_default(hil_board):
    assert hil_board.eds == resources.DEFAULT_EDS and hil_board.plant is default_plant
    assert hil_board.firmware == resources.DEFAULT_FIRMWARE
"""
    )
    pytester.runpytest("-p", "no:cacheprovider").assert_outcomes(passed=1)
    assert default_plant  # the default the test compares with


@pytest.mark.parametrize(
    ("spelled", "says"),
    [
        ("toy_plant", "expected module:callable, got 'toy_plant'"),
        ("no_such_module:make", "cannot import no_such_module"),
        ("toy_plant:nothing", "toy_plant has no nothing"),
        ("toy_plant:made", "not callable"),
    ],
)
def test_a_bad_plant_factory_is_one_line_naming_it(
    pytester: pytest.Pytester, spelled: str, says: str
) -> None:
    _project(pytester, f"hil_plant = {spelled}\n")
    pytester.makepyfile(test_board="def test_board(hil_board):\n    pass\n")
    pytester.syspathinsert()
    result = pytester.runpytest("-p", "no:cacheprovider")
    assert result.ret != 0
    result.stdout.fnmatch_lines([f"hil_plant*{says}*", "ERROR *Failed: hil_plant*"])
    assert "During handling" not in result.stdout.str() and "Traceback" not in result.stdout.str()


def test_a_bad_table_is_one_line_naming_it(pytester: pytest.Pytester) -> None:
    (pytester.path / "board.toml").write_text("[node]\nbogus = 1\n")
    pytester.makeini("[pytest]\nhil_table = board.toml\n")
    pytester.makepyfile(test_board="def test_board(hil_board):\n    pass\n")
    result = pytester.runpytest("-p", "no:cacheprovider")
    assert result.ret != 0
    result.stdout.fnmatch_lines(["hil_table */board.toml: *", "ERROR *Failed: hil_table*"])


def test_with_durations_the_longest_run_first_and_their_hang_guard_grows(pytester: pytest.Pytester) -> None:
    durations = {"test_order.py::test_short": 1.0, "test_order.py::test_long": 200.0}
    (pytester.path / "durations.json").write_text(json.dumps(durations))
    pytester.makeini("[pytest]\nhil_durations = durations.json\n")
    pytester.makepyfile(
        test_order="""
import pytest

def test_short(request):
    pass

def test_unknown(request):
    pass

def test_long(request):
    assert request.node.get_closest_marker("timeout").args == (4000,)
"""
    )
    result = pytester.runpytest("-p", "no:cacheprovider", "-v", "--timeout=600")
    result.assert_outcomes(passed=3)
    result.stdout.fnmatch_lines(["*test_long PASSED*", "*test_unknown PASSED*", "*test_short PASSED*"])


def test_a_project_that_sets_nothing_keeps_its_order_and_its_tests(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(test_plain="def test_b():\n    pass\n\ndef test_a():\n    pass\n")
    result = pytester.runpytest("-p", "no:cacheprovider", "-v")
    result.assert_outcomes(passed=2)
    result.stdout.fnmatch_lines(["*test_b PASSED*", "*test_a PASSED*"])


def test_a_failed_scenario_names_its_evidence(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(
        test_evidence="""
def test_fails(request):
    request.node.hil_evidence = "trace: out/t/trace.rrd, bus log: out/t/bus.log"
    assert False
"""
    )
    result = pytester.runpytest("-p", "no:cacheprovider")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(
        ["*failed scenarios: where to look*", "FAILED test_evidence.py::test_fails: trace: out/t/trace.rrd*"]
    )


def test_the_fixtures_a_scenario_uses_come_from_the_plugin(pytester: pytest.Pytester) -> None:
    result = pytester.runpytest("-p", "no:cacheprovider", "--fixtures")
    for fixture in ("make_scenario", "make_robot", "private_bus", "scenario_dir", "hil_board"):
        result.stdout.fnmatch_lines([f"{fixture}*"])
    assert Path(resources.DEFAULT_TABLE).is_file()


BUS_TEST = """
import argparse
import pytest
from hilrig.pytest_plugin.fixtures import RUN_BITRATE, _scenario_bus, _timed_bus

def bus(request, hil_board, given=RUN_BITRATE):
    return _scenario_bus(request.node, request.config.getoption("hil_timed_bus"), given, hil_board)

def test_the_runs_bus_is_the_tables_by_default(request, hil_board):
    assert request.config.getoption("hil_timed_bus") == "table"
    assert bus(request, hil_board) == (1_000_000, "1 Mbit/s")
    runs = {"500k": (500_000, "500 kbit/s"), "ideal": (None, "ideal: --hil-timed-bus ideal")}
    for run, expected in runs.items():
        assert _scenario_bus(request.node, _timed_bus(run), RUN_BITRATE, hil_board) == expected, run
    with pytest.raises(argparse.ArgumentTypeError, match="a bit rate .*, table or ideal, got 'fast'"):
        _timed_bus("fast")

@pytest.mark.ideal_bus("its point needs every frame in its cycle")
def test_marked(request, hil_board):
    assert bus(request, hil_board) == (None, "ideal: its point needs every frame in its cycle")
    assert bus(request, hil_board, 250_000) == (250_000, "250 kbit/s"), "its own bitrate= wins"

def test_its_own(request, hil_board):
    assert bus(request, hil_board, "table") == (hil_board.table.board.node.bitrate, "1 Mbit/s")
    assert bus(request, hil_board, None) == (None, "ideal: the scenario's own make_scenario(bitrate=None)")

@pytest.mark.ideal_bus()
def test_marked_without_why(request, hil_board):
    bus(request, hil_board)
"""

SUMMARY_TEST = """
import pytest
from hilrig.wire.bustime import BUS_PROPERTY

@pytest.mark.parametrize("label", ["1 Mbit/s", "1 Mbit/s", "ideal: why", "250 kbit/s"])
def test_one(record_property, label):
    record_property(BUS_PROPERTY, label)
"""


def test_a_scenarios_bus_and_the_summary_of_the_runs_buses(pytester: pytest.Pytester) -> None:
    # One run (a pytester run costs seconds): the bus each way a scenario can be given one, and
    # the terminal summary's count of the scenarios of each bus (their BUS_PROPERTY).
    _project(pytester, "hil_table = board.toml\nhil_plant = toy_plant:make_plant\n")
    pytester.makepyfile(test_bus=BUS_TEST, test_summary=SUMMARY_TEST)
    result = pytester.runpytest("-p", "no:cacheprovider")
    result.assert_outcomes(passed=7, failed=1)
    result.stdout.fnmatch_lines(
        [
            "*ideal_bus(why): say why the scenario needs the ideal bus*",
            "*the lockstep scenarios' bus*",
            "3 scenarios on the timed bus (1 Mbit/s 2, 250 kbit/s 1)",
            "1 scenarios on the ideal bus, which carries any load:",
            "    1 why",
        ]
    )
