"""`hilrig bus` without a bus: what a guest is shown of the host (the folders a command works in,
/tmp included, or a one-line error naming what cannot be seen), what its script runs with, the
command's refusals; and the firmware choice no bus wrapper may make: a project's `hil_firmware`
wins under user-mode Linux, the checkout's default turns to its release build there, and pytest's
header says which firmware and why. The guests themselves boot in tools/other_project.py's run."""

from __future__ import annotations

import shlex
import sys
from pathlib import Path

import pytest

from hilrig import resources
from hilrig.cli import main
from hilrig.errors import BusUnavailableError
from hilrig.session import guests, vcan


def test_a_folder_under_tmp_is_shown_by_its_top_folder_so_a_venv_comes_whole() -> None:
    wanted = [Path("/tmp/proj/venv/bin"), Path("/home/me/x"), Path("/tmp/proj/lamp"), Path("/tmp/other")]
    assert vcan.tmp_binds(wanted) == [Path("/tmp/other"), Path("/tmp/proj")]
    assert vcan.tmp_binds([Path("/home/me")]) == []
    assert vcan.tmp_binds([Path("/tmp"), Path("/tmp/proj")]) is None  # the host's /tmp itself


def test_the_guest_sees_the_working_folder_the_python_environment_and_the_paths_named(tmp_path: Path) -> None:
    named = tmp_path / "project" / "venv" / "bin"
    named.mkdir(parents=True)
    report = tmp_path / "results.xml"
    report.write_text("")
    command = ["pytest", f"--junitxml={report}", str(named), "not-a-path", str(tmp_path / "missing")]
    folders = vcan.visible_folders(command, Path("/home"))
    assert {Path("/home"), Path(sys.prefix), named, report} <= set(folders)
    assert tmp_path / "missing" not in folders


def test_a_path_under_a_folder_the_guest_has_its_own_of_is_one_line_naming_it(tmp_path: Path) -> None:
    with pytest.raises(
        BusUnavailableError, match=r"^/proc/self/status cannot be seen inside .*its /proc is its own"
    ):
        vcan.visible_folders(["cat", "/proc/self/status"], tmp_path)


def test_the_guests_command_runs_in_this_folder_with_the_hil_variables_and_its_bus_path(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv("HIL_SEED", "7")
    monkeypatch.delenv("HIL_FIRMWARE", raising=False)
    monkeypatch.setenv("SECRET_OF_THE_HOST", "x")
    lines = vcan.command_lines(["pytest", "-k", "a b"], Path("/work/my project"), "uml:7.2.7")
    assert lines[0] == "cd '/work/my project'"
    assert "export HIL_SEED=7" in lines and "export HIL_BUS_PATH=uml:7.2.7" in lines
    assert not any("HIL_FIRMWARE" in line or "SECRET_OF_THE_HOST" in line for line in lines)
    assert lines[-2:] == ["set +e", "pytest -k 'a b'"]


def test_user_mode_linux_puts_the_hosts_tmp_folders_back_over_its_own_tmp(tmp_path: Path) -> None:
    kernel = tmp_path / "usr" / "bin" / "linux.uml"
    script = guests.uml_script(
        ["true"], Path("/tmp/proj"), [Path("/tmp/proj/lamp"), Path("/home")], "7.2.7", Path("/x.rc"), kernel
    )
    assert "mount -t tmpfs tmpfs /tmp" in script
    assert "mkdir -p /tmp/proj && mount --bind /run/host-tmp/proj /tmp/proj" in script
    assert f"mount --bind {tmp_path / 'usr' / 'lib' / 'uml' / 'modules'} /lib/modules" in script
    assert "echo $? > /x.rc" in script
    whole_tmp = guests.uml_script(["true"], Path("/tmp"), [Path("/tmp")], "7.2.7", Path("/x.rc"), kernel)
    assert "tmpfs /tmp" not in whole_tmp


@pytest.mark.parametrize(
    ("version", "options"), [("6.1.0", []), ("6.16.2", ["seccomp=on"]), ("7.2.7", ["seccomp=on"])]
)
def test_seccomp_traps_the_guests_calls_from_kernel_6_16_on(version: str, options: list[str]) -> None:
    assert guests.uml_options(version) == options


def test_a_command_that_is_not_here_is_one_line_and_exit_127(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bus", "--", "no-such-command-of-hilrig"]) == 127
    assert capsys.readouterr().err == "hilrig bus: error: no-such-command-of-hilrig: command not found\n"


def test_no_command_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bus"]) == 2
    assert "no command given" in capsys.readouterr().err


def test_which_prints_the_forced_path_and_runs_nothing(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bus", "--uml", "--which", "--", "false"]) == 0
    assert capsys.readouterr().out == "uml\n"


def test_help_says_the_paths_and_what_to_install(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bus", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    for needed in (
        "native",
        "user-mode Linux",
        "micro-VM",
        "apt-get install user-mode-linux",
        "virtme-ng",
        "130",
    ):
        assert needed in text


def _checkout_with_release(monkeypatch: pytest.MonkeyPatch, root: Path) -> Path:
    release = root / "build" / "release" / "bin" / "joint-firmware"
    release.parent.mkdir(parents=True)
    release.write_text("")
    monkeypatch.setattr(resources, "CHECKOUT", root)
    monkeypatch.delenv("HIL_FIRMWARE", raising=False)
    return release


def test_the_checkouts_default_firmware_is_its_release_build_under_user_mode_linux_only(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    release = _checkout_with_release(monkeypatch, tmp_path)
    monkeypatch.setenv("HIL_BUS_PATH", "uml:7.2.7")
    assert resources._default_firmware()[0] == release
    monkeypatch.setenv("HIL_BUS_PATH", "native")
    assert resources._default_firmware() == (
        tmp_path / "build" / "bin" / "joint-firmware",
        "the checkout's build",
    )
    monkeypatch.setenv("HIL_FIRMWARE", "/elsewhere/mutant")
    assert resources._default_firmware() == (Path("/elsewhere/mutant"), "$HIL_FIRMWARE")


def test_a_projects_hil_firmware_wins_under_user_mode_linux_and_the_header_says_so(
    pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("HIL_BUS_PATH", "uml:7.2.7")
    monkeypatch.delenv("HIL_FIRMWARE", raising=False)
    pytester.makeini("[pytest]\nhil_firmware = build/lamp-firmware\n")
    pytester.makepyfile(
        test_board="def test_board(hil_board):\n    assert hil_board.firmware.name == 'lamp-firmware'\n"
    )
    result = pytester.runpytest("-p", "no:cacheprovider")
    result.assert_outcomes(passed=1)
    firmware = pytester.path / "build" / "lamp-firmware"
    result.stdout.fnmatch_lines(
        [f"hilrig: firmware {firmware} (hil_firmware of tox.ini)", "hilrig: bus path uml:7.2.7"]
    )


def test_a_project_of_no_board_gets_no_header_line(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(test_plain="def test_plain():\n    pass\n")
    result = pytester.runpytest("-p", "no:cacheprovider")
    result.assert_outcomes(passed=1)
    assert "hilrig:" not in result.stdout.str()


def test_tools_with_vcan_is_this_command() -> None:
    wrapper = (Path(__file__).resolve().parents[2] / "tools" / "with-vcan").read_text()
    last = [line for line in wrapper.splitlines() if line.strip()][-1]
    assert shlex.split(last) == ["exec", "$python", "-m", "hilrig.cli", "bus", "$@"]
