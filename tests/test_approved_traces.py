"""The approved traces catch what a scenario's own assertions let through: the joint's firmware
with one line changed (the duty the drive arbiter passes on 0.1 % low), built beside `make build`'s from that
build's own commands (one object compiled again, its library and the firmware linked again, in
<build>/approved-proof/), runs the watchdog scenario: its own assertions (the trip on its cycle,
the drive cut there) pass, its approved trace (tests/approved/) fails it, naming the first
divergent cycle, field and values."""

from __future__ import annotations

import re
import shlex
import shutil
import subprocess
from pathlib import Path

import pytest

from hilrig import resources
from hilrig.resources import FIRMWARE_VARIABLE

# A rig check: it patches the checkout's own firmware, whatever $HIL_FIRMWARE is.
pytestmark = [pytest.mark.bus, pytest.mark.rig_check]

REPO = Path(__file__).resolve().parent.parent
SCENARIO = "tests/test_protection_rules.py::test_watchdog_trips_on_its_cycle_and_cuts_the_drive_there"
SOURCE = "firmware/joint/modules/DriveArbiter.cpp"
LINE = "return std::clamp(duty, -limit, limit);"
CHANGED = "return std::clamp(duty * 0.999F, -limit, limit);"
TARGET = "bin/joint-firmware"


def _run(command: str, cwd: Path) -> None:
    done = subprocess.run(command, shell=True, cwd=cwd, capture_output=True, text=True, check=False)
    assert done.returncode == 0, f"{command}\n{done.stdout}{done.stderr}"


def patched_firmware(build: Path, out: Path) -> Path:
    """`build`'s joint firmware with SOURCE's LINE changed: its ninja commands, with that one
    object compiled from the patched copy, put into a copy of its library, and linked into
    `out`; nothing in `build` is written."""
    commands = subprocess.run(
        ["ninja", "-C", str(build), "-t", "commands", TARGET], capture_output=True, text=True, check=True
    ).stdout.splitlines()
    source = REPO / SOURCE
    text = source.read_text()
    assert text.count(LINE) == 1, f"{SOURCE} no longer holds `{LINE}` once: update this test"
    out.mkdir(parents=True, exist_ok=True)
    patched = out / source.name
    patched.write_text(text.replace(LINE, CHANGED))
    compile_line = next(c for c in commands if c.endswith(f"-c {source}"))
    words = shlex.split(compile_line)
    obj = words[words.index("-o") + 1]
    for flag in ("-MD",):
        words.remove(flag)
    for flag in ("-MT", "-MF"):
        at = words.index(flag)
        del words[at : at + 2]
    new_obj = out / Path(obj).name
    words[words.index("-o") + 1] = str(new_obj)
    words[-1] = str(patched)
    _run(shlex.join(words), build)
    library = next(
        w for c in commands if obj in c and "ar qc " in c for w in shlex.split(c) if w.endswith(".a")
    )
    new_library = out / Path(library).name
    shutil.copyfile(build / library, new_library)
    _run(shlex.join(["ar", "r", str(new_library), str(new_obj)]), out)
    link = commands[-1]
    assert f"-o {TARGET}" in link, link
    firmware = out / Path(TARGET).name
    _run(link.replace(f"-o {TARGET}", f"-o {firmware}").replace(f" {library} ", f" {new_library} "), build)
    return firmware


def test_a_one_line_firmware_change_fails_the_scenario_on_its_approved_trace(
    pytester: pytest.Pytester, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    build = resources.DEFAULT_FIRMWARE.parent.parent
    firmware = patched_firmware(build, build / "approved-proof")
    monkeypatch.setenv(FIRMWARE_VARIABLE, str(firmware))
    monkeypatch.setenv("HIL_OUT_DIR", str(tmp_path / "out"))
    monkeypatch.delenv("CI", raising=False)
    # In this process (its imports are done), with this project's pytest.ini and conftest.py.
    result = pytester.runpytest_inprocess(
        str(REPO / SCENARIO),
        "-c",
        str(REPO / "pytest.ini"),
        "--rootdir",
        str(REPO),
        "-p",
        "no:cacheprovider",
        "--hil-approved=check",
    )
    output = result.stdout.str()
    result.assert_outcomes(failed=1)
    assert f"firmware {firmware}" in output, f"not the patched firmware:\n{output}"
    assert re.search(r"differs from its approved trace \S*tests/approved/test_protection_rules\.", output), (
        output
    )
    assert re.search(r"first divergence: motor_duty(_command)? at cycle \d+ \(t = ", output), output
