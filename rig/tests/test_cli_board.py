"""The CLI knows its board: which table a command uses when it is given no --table (the order of
`resources.TABLE_ORDER`, no bus), and the refusal of every write to a node whose 0x1018 identity
is not the table's, against the in-process FakeJointNode on python-can's virtual bus. The same
refusals against the real firmware: tests/test_cli.py."""

from __future__ import annotations

from pathlib import Path

import pytest

from hilrig import resources
from hilrig.cli import EXIT_OK, EXIT_USAGE, common, main
from hilrig.errors import ConfigurationError
from hilrig.session.fake_node import FakeJointNode
from hilrig.table import RigTable

REPO = Path(__file__).resolve().parents[2]
LAMP = REPO / "examples" / "other-project" / "board.toml"
TABLE = RigTable.load()
KP = TABLE.field("velocity_kp")
OTHER_PRODUCT = 0x4F544852


def joint_copy(path: Path, product_code: int = OTHER_PRODUCT) -> Path:
    """The joint's table with another product code: the same names, another board."""
    text = resources.DEFAULT_TABLE.read_text()
    line = f"product_code = 0x{TABLE.board.node.product_code:08X}"
    assert line in text
    path.write_text(text.replace(line, f"product_code = 0x{product_code:08X}"))
    return path


@pytest.fixture
def folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty working folder, with no $HIL_TABLE, and the generated files' cache inside it."""
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    monkeypatch.delenv(resources.TABLE_ENV, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    return work


# --- which table --------------------------------------------------------------------------------
def choice(folder: Path, given: Path | None = None, **environ: str) -> resources.TableChoice:
    return resources.chosen_table(given, cwd=folder, environ=environ)


def test_with_nothing_in_the_folder_the_default_table(folder: Path) -> None:
    chosen = choice(folder)
    assert (chosen.path, chosen.source, chosen.is_default) == (resources.DEFAULT_TABLE, "the default", True)


def test_each_source_wins_over_the_ones_after_it(folder: Path) -> None:
    (folder / "board.toml").write_text(LAMP.read_text())
    assert choice(folder) == resources.TableChoice(folder / "board.toml", "board.toml in this folder")

    # a pytest.ini without hil_table says nothing about the table
    (folder / "pytest.ini").write_text("[pytest]\naddopts = -q\n")
    assert choice(folder).path == folder / "board.toml"

    (folder / "tables").mkdir()
    joint_copy(folder / "tables" / "fan.toml")
    (folder / "pytest.ini").write_text("[pytest]\nhil_table = tables/fan.toml\n")
    assert choice(folder) == resources.TableChoice(
        folder / "tables" / "fan.toml", "hil_table of pytest.ini in this folder"
    )

    joint_copy(folder / "env.toml")
    assert choice(folder, HIL_TABLE="env.toml") == resources.TableChoice(folder / "env.toml", "$HIL_TABLE")

    given = folder / "tables" / "given.toml"
    assert choice(folder, given, HIL_TABLE="env.toml") == resources.TableChoice(given, "--table")


def test_a_source_that_names_no_file_is_refused_saying_where(folder: Path) -> None:
    with pytest.raises(ConfigurationError, match=r"^\$HIL_TABLE names .*missing\.toml, which is no file"):
        choice(folder, HIL_TABLE="missing.toml")
    (folder / "pytest.ini").write_text("[pytest]\nhil_table = nowhere/board.toml\n")
    with pytest.raises(ConfigurationError, match=r"^hil_table of pytest.ini in this folder names"):
        choice(folder)
    (folder / "pytest.ini").write_text("hil_table = outside any section\n")
    with pytest.raises(ConfigurationError, match=r"pytest.ini is not an ini file"):
        choice(folder)


def test_fields_in_a_folder_with_its_own_board_toml_lists_that_board(
    folder: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["fields"]) == EXIT_OK
    out, err = capsys.readouterr()
    assert "velocity_kp" in out and err == "", "the default table, and nothing said about it"

    (folder / "board.toml").write_text(LAMP.read_text())
    assert main(["fields"]) == EXIT_OK
    out, err = capsys.readouterr()
    names = [line.split()[0] for line in out.splitlines()[1:]]
    assert names == [entry.name for entry in RigTable.load(LAMP).board.entries]
    assert "velocity_kp" not in names
    assert err == "hilrig: table ./board.toml (board.toml in this folder)\n"


def test_a_missing_table_of_the_environment_is_exit_code_2_in_one_line(
    folder: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(resources.TABLE_ENV, "missing.toml")
    assert main(["fields"]) == EXIT_USAGE
    err = capsys.readouterr().err
    assert err.startswith("hilrig fields: error: $HIL_TABLE names ") and err.count("\n") == 1, err


def test_the_order_is_in_the_help_of_hilrig_and_of_every_table_option(
    capsys: pytest.CaptureFixture[str],
) -> None:
    def flat(text: str) -> str:
        return " ".join(text.split())

    assert main(["--help"]) == EXIT_OK
    assert flat(resources.TABLE_ORDER) in flat(capsys.readouterr().out)
    for command in (["fields"], ["set"], ["sdo", "write"], ["monitor"]):
        assert main([*command, "--help"]) == EXIT_OK
        assert flat(resources.TABLE_ORDER) in flat(capsys.readouterr().out), command


# --- writes to the wrong board ------------------------------------------------------------------
def on_bus(channel: str) -> list[str]:
    return ["--interface", "virtual", "--channel", channel, "--sdo-timeout", "2"]


WRITES = [
    pytest.param(["set", f"velocity_kp={KP.max / 2:g}"], id="set"),
    pytest.param(["sdo", "write", f"0x{KP.index:04X}", f"{KP.max / 2:g}"], id="sdo-write"),
]


@pytest.mark.parametrize("command", WRITES)
def test_a_write_to_a_node_of_another_product_is_refused_and_nothing_written(
    command: list[str],
    fake: FakeJointNode,
    channel: str,
    folder: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    other = joint_copy(folder / "board.toml")
    before = fake.local.sdo[KP.index].raw
    assert main([*command, *on_bus(channel)]) == EXIT_USAGE
    out, err = capsys.readouterr()
    node = TABLE.board.node
    assert out == ""
    assert err.splitlines() == [
        "hilrig: table ./board.toml (board.toml in this folder)",
        f"hilrig {command[0] if command[0] == 'set' else 'sdo write'}: error: node "
        f"0x{node.default_node_id:02X} is vendor 0x{node.vendor_id:08X} product 0x{node.product_code:08X}, "
        f"not the table's vendor 0x{node.vendor_id:08X} product 0x{OTHER_PRODUCT:08X} (./{other.name}): "
        "nothing written; give that board's --table, or --force to write anyway",
    ]
    assert fake.local.sdo[KP.index].raw == before

    assert main([*command, *on_bus(channel), "--force"]) == EXIT_OK
    err = capsys.readouterr().err
    assert "writing anyway (--force)" in err.splitlines()[1], err
    assert fake.local.sdo[KP.index].raw == pytest.approx(KP.max / 2)


def test_a_write_with_the_right_table_says_nothing_about_identity(
    fake: FakeJointNode, channel: str, folder: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (folder / "board.toml").write_text(resources.DEFAULT_TABLE.read_text())  # the joint's, copied
    assert main(["set", f"velocity_kp={KP.max / 4:g}", *on_bus(channel)]) == EXIT_OK
    assert capsys.readouterr().err == "hilrig: table ./board.toml (board.toml in this folder)\n"
    assert fake.local.sdo[KP.index].raw == pytest.approx(KP.max / 4)


@pytest.mark.parametrize(
    "command", [["set"], ["sdo", "write"], ["params", "load"], ["flash"], ["pdo"], ["capture"]], ids=" ".join
)
def test_every_writing_command_has_force(command: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    assert main([*command, "--help"]) == EXIT_OK
    assert " ".join(common.FORCE_HELP.split()) in " ".join(capsys.readouterr().out.split())


# --- Ctrl-C at start-up -------------------------------------------------------------------------
INTERRUPT_DURING_IMPORTS = """
import signal, sys

class CtrlC:
    def find_spec(self, name, path=None, target=None):
        if name == "hilrig.cli.common":  # what the console script imports, half-way
            signal.raise_signal(signal.SIGINT)
        return None

sys.meta_path.insert(0, CtrlC())
from hilrig.cli import main
sys.exit(main(["fields"]))
"""


def test_ctrl_c_while_the_command_is_still_importing_is_one_line_and_130(tmp_path: Path) -> None:
    import subprocess
    import sys

    done = subprocess.run(
        [sys.executable, "-c", INTERRUPT_DURING_IMPORTS],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=120,
        check=False,
    )
    assert (done.returncode, done.stdout, done.stderr) == (130, "", "hilrig: interrupted\n")


def test_ctrl_c_while_the_parser_is_built_is_one_line_and_130(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import signal

    import hilrig.cli

    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler, "imported: Python's own again"

    def interrupted(argv: object = None) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(hilrig.cli, "build_parser", interrupted)
    assert main(["fields"]) == 130
    assert capsys.readouterr().err == "hilrig: interrupted\n"
