"""The run description (hilrig.session.run): built from a command line and from pytest's options by
the same rules, its control period's default and range the table's, refused out of range in one
line naming the option and the range; `hilrig sim` refuses it with the usage exit code before
anything starts."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path
from typing import Any

import pytest

from hilrig.cli import EXIT_USAGE, main
from hilrig.engine.timing import TimingMode
from hilrig.session.firmware import firmware_argv, firmware_mode
from hilrig.session.run import (
    REALTIME_FIRMWARE_PERIOD_US,
    RigRun,
    RunDescription,
    RunOptionError,
    TraceRun,
)
from hilrig.table import RigTable


@pytest.fixture(scope="module")
def table() -> RigTable:
    return RigTable.load()


def parse(*argv: str, **defaults: Any) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", type=Path, default=Path("out/x"))
    RunDescription.add_arguments(parser, **defaults)
    return parser.parse_args(argv)


def test_the_period_is_the_tables_unless_the_command_line_gives_one(table: RigTable) -> None:
    run = RunDescription.from_arguments(parse(), table)
    assert run.rig.period_us is None
    assert run.rig.cycle_us(table) == table.board.node.period_us
    assert run.firmware.own_period_us(run.rig, table) == table.board.node.period_us
    given = RunDescription.from_arguments(parse("--period-us", "2000"), table)
    assert given.rig.cycle_us(table) == 2000 and given.out_dir == Path("out/x")


def test_a_free_running_firmware_keeps_its_own_period(table: RigTable) -> None:
    run = RunDescription(TraceRun(Path("o")), rig=RigRun(timing=TimingMode.REALTIME, period_us=50_000))
    assert run.firmware.own_period_us(run.rig, table) == REALTIME_FIRMWARE_PERIOD_US


@pytest.mark.parametrize("period", ["99", "1000001"])
def test_a_period_outside_the_tables_range_names_the_option_and_the_range(
    table: RigTable, period: str
) -> None:
    with pytest.raises(RunOptionError) as caught:
        RunDescription.from_arguments(parse("--period-us", period), table)
    node = table.board.node
    assert str(caught.value) == (
        f"--period-us: expected a control period of {node.period_us_min}..{node.period_us_max} us "
        f"(the table's [node] period_us_min..period_us_max), got {period}"
    )


def test_a_command_sets_its_own_defaults_and_picks_its_options(table: RigTable) -> None:
    args = parse(seed=7)
    assert RunDescription.from_arguments(args, table).rig.seed == 7
    parser = argparse.ArgumentParser()
    RunDescription.add_arguments(parser, "period_us")
    assert not hasattr(parser.parse_args([]), "seed")
    with pytest.raises(ValueError, match="no run option no_such"):
        RunDescription.add_arguments(argparse.ArgumentParser(), "no_such")


class FakeOptions:
    """pytest's `config.getoption` over a dict: what `from_pytest` reads."""

    def __init__(self, **given: Any) -> None:
        self.given = given

    def getoption(self, name: str, default: Any = None) -> Any:
        return self.given.get(name, default)


def test_pytest_options_follow_the_command_lines_rules(table: RigTable) -> None:
    flags = [flag for flag, _ in RunDescription.pytest_options()]
    assert flags == ["--hil-period-us", "--hil-boot-timeout", "--hil-tpdo-timeout"]
    base = RunDescription(TraceRun(Path("o")), rig=RigRun(seed=3))
    assert RunDescription.from_pytest(FakeOptions(), base, table) == base
    run = RunDescription.from_pytest(FakeOptions(hil_period_us=500, hil_seed=9), base, table)
    assert run.rig == dataclasses.replace(base.rig, period_us=500)  # --seed is no pytest option
    with pytest.raises(RunOptionError, match=r"^--period-us: expected a control period of 100\.\."):
        RunDescription.from_pytest(FakeOptions(hil_period_us=50), base, table)


def test_the_boot_timeout_is_a_run_option(table: RigTable) -> None:
    run = RunDescription.from_arguments(parse("--boot-timeout", "120"), table)
    assert run.firmware.boot_timeout_s == 120.0
    with pytest.raises(SystemExit):
        parse("--boot-timeout", "0")


def test_the_tpdo_timeout_is_a_run_option_of_the_command_line_and_of_pytest(table: RigTable) -> None:
    run = RunDescription.from_arguments(parse("--tpdo-timeout", "9"), table)
    assert run.rig.tpdo_timeout_s == 9.0
    base = RunDescription(TraceRun(Path("out")))
    given = RunDescription.from_pytest(FakeOptions(hil_tpdo_timeout=7.5), base, table)
    assert given.rig.tpdo_timeout_s == 7.5
    with pytest.raises(SystemExit):
        parse("--tpdo-timeout", "0")


def test_one_timing_vocabulary_the_firmwares_words_only_on_its_command_line() -> None:
    assert firmware_mode(TimingMode.REALTIME) == "free"
    assert firmware_mode("lockstep") == "lockstep"
    with pytest.raises(ValueError, match="timing mode 'free': expected one of lockstep, realtime"):
        firmware_mode("free")
    argv = firmware_argv(Path("fw"), "vcan0", 5, None, mode=TimingMode.REALTIME)
    assert argv[-2:] == ["--mode", "free"] and "--period-us" not in argv


def test_sim_refuses_a_period_out_of_range_before_anything_starts(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(["sim", "--out", str(tmp_path / "run"), "--period-us", "50"])
    err = capsys.readouterr().err.strip()
    assert code == EXIT_USAGE
    assert "--period-us: expected a control period of 100..1000000 us" in err and "\n" not in err
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("command", ["sim", "soak"])
def test_sim_and_soak_take_node_firmware_and_eds_from_the_run_description(
    table: RigTable, command: str, tmp_path: Path
) -> None:
    from hilrig.cli import build_parser

    parser = build_parser()
    default = RunDescription.from_arguments(parser.parse_args([command]), table)
    assert default.node_id(table) == table.board.node.default_node_id
    assert (default.firmware.executable, default.rig.eds) == (
        RunDescription(TraceRun(Path("o"))).firmware.executable,
        RigRun().eds,
    )
    eds = tmp_path / "board.eds"
    eds.write_text("[1000]\nParameterName=Device type\n")
    given = RunDescription.from_arguments(
        parser.parse_args([command, "-n", "0x11", "--eds", str(eds)]), table
    )
    assert (given.node_id(table), given.rig.eds) == (0x11, eds)


@pytest.mark.parametrize("command", ["sim", "soak"])
def test_a_node_id_out_of_range_is_the_same_usage_error_for_sim_and_soak(
    capsys: pytest.CaptureFixture[str], command: str
) -> None:
    assert main([command, "--node-id", "128"]) == EXIT_USAGE
    assert "expected a node id 1..127 (decimal or 0x hex, e.g. 0x10), got 128" in capsys.readouterr().err
