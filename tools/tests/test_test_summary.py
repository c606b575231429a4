"""tools/test-summary.py: the run's closing lines from the stages' JUnit XML, each failure with
the pictures its scenario attached."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest

TOOLS = Path(__file__).resolve().parent.parent


def load_summary() -> ModuleType:
    sys.path.insert(0, str(TOOLS))  # its own import of scenario_shards
    try:
        spec = importlib.util.spec_from_file_location("test_summary_tool", TOOLS / "test-summary.py")
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = module  # its dataclasses look their module up
        spec.loader.exec_module(module)
        return module
    finally:
        sys.path.remove(str(TOOLS))


def junit(*cases: str) -> str:
    return f'<testsuites><testsuite name="pytest">{"".join(cases)}</testsuite></testsuites>'


def test_a_failure_lists_the_pictures_it_attached(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    summary = load_summary()
    (tmp_path / "cpp.xml").write_text(junit('<testcase classname="Cia301" name="codes"/>'))
    (tmp_path / "cortex-m.xml").write_text(junit('<testcase classname="cortex_m" name="core"/>'))
    (tmp_path / "python-unit.xml").write_text(junit('<testcase classname="t" name="a"/>'))
    (tmp_path / "browser.xml").write_text(junit('<testcase classname="b" name="joint"/>'))
    failed = (
        '<testcase classname="tests.test_joint" name="test_step"><failure message="x"/>'
        "<system-out>[[ATTACHMENT|/out/p/output_velocity-settles_within.png]]\n</system-out></testcase>"
    )
    (tmp_path / "scenarios.xml").write_text(junit(failed, '<testcase classname="tests.t" name="ok"/>'))
    assert summary.main(["test-summary.py", str(tmp_path)]) == 1
    out = capsys.readouterr().out.splitlines()
    at = out.index("    FAILED tests.test_joint::test_step")
    assert out[at + 1] == "        picture: /out/p/output_velocity-settles_within.png"
    assert out[-1] == "5 passed, 1 failed"


def test_the_requirements_coverage_gathers_every_stage_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    summary = load_summary()
    for name in ("cpp.xml", "cortex-m.xml", "python-unit.xml", "browser.xml"):
        (tmp_path / name).write_text(junit('<testcase classname="t" name="a"/>'))

    def case(name: str, inner: str, *ids: str) -> str:
        properties = "".join(f'<property name="requirement" value="{id_}"/>' for id_ in ids)
        head = f'<testcase classname="tests.t" name="{name}">'
        return f"{head}<properties>{properties}</properties>{inner}</testcase>"

    (tmp_path / "scenarios-lane-1.xml").write_text(junit(case("a", "", "CTRL_01", "PROT_01")))
    (tmp_path / "scenarios-lane-2.xml").write_text(
        junit(case("b", '<failure message="x"/>', "PROT_01"), case("c", "<skipped/>", "NMT_01"))
    )
    listed = tmp_path / "requirements.toml"
    listed.write_text(
        "".join(
            f'[[requirement]]\nid = "{id_}"\ntitle = "t"\n'
            for id_ in ("CTRL_01", "PROT_01", "NMT_01", "HB_01")
        )
    )
    assert summary.main(["test-summary.py", str(tmp_path), "--requirements", str(listed)]) == 1
    out = capsys.readouterr().out.splitlines()
    at = out.index(
        "requirements of requirements.toml: 1 of 4 verified by a passing test,"
        " 1 failed, 1 skipped, 1 uncovered"
    )
    assert out[at + 1 : at + 4] == ["    failed: PROT_01", "    skipped: NMT_01", "    uncovered: HB_01"]
    assert out[-1] == "5 passed, 1 failed, 1 skipped"


def test_the_checkouts_requirements_file_is_the_default(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    summary = load_summary()
    assert summary.main(["test-summary.py", str(tmp_path), "--bus-only"]) == 1
    assert "requirements of requirements.toml: 0 of " in capsys.readouterr().out


def test_the_bus_stage_says_how_many_scenarios_ran_on_each_firmware_platform(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    summary = load_summary()
    for name in ("cpp.xml", "cortex-m.xml", "python-unit.xml", "browser.xml"):
        (tmp_path / name).write_text(junit('<testcase classname="t" name="a"/>'))

    def case(name: str, inner: str, *platforms: str) -> str:
        properties = "".join(f'<property name="firmware_platform" value="{p}"/>' for p in platforms)
        head = f'<testcase classname="tests.t" name="{name}">'
        return f"{head}<properties>{properties}</properties>{inner}</testcase>"

    (tmp_path / "scenarios.xml").write_text(
        junit(
            case("a[linux]", "", "linux"),
            case("a[qemu-virt]", '<failure message="x"/>', "qemu-virt"),
            case("both", "", "linux", "qemu-virt"),
            case("skipped", "<skipped/>", "qemu-virt"),
        )
    )
    assert (
        summary.main(["test-summary.py", str(tmp_path), "--requirements", str(tmp_path / "none.toml")]) == 1
    )
    out = capsys.readouterr().out.splitlines()
    assert (
        "    firmware platforms: linux 2 ran (2 passed, 0 failed), qemu-virt 2 ran (1 passed, 1 failed)"
        in out
    )


def test_the_bus_stage_says_which_scenarios_ran_on_the_ideal_bus_and_why(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    summary = load_summary()
    for name in ("cpp.xml", "cortex-m.xml", "python-unit.xml", "browser.xml"):
        (tmp_path / name).write_text(junit('<testcase classname="t" name="a"/>'))

    def case(name: str, inner: str, *buses: str) -> str:
        properties = "".join(f'<property name="hil_bus" value="{b}"/>' for b in buses)
        head = f'<testcase classname="tests.t" name="{name}">'
        return f"{head}<properties>{properties}</properties>{inner}</testcase>"

    (tmp_path / "scenarios.xml").write_text(
        junit(
            case("a", "", "1 Mbit/s"),
            case("b", '<failure message="x"/>', "1 Mbit/s", "1 Mbit/s"),
            case("c", "", "ideal: the full mapping does not fit"),
            case("d", "", "ideal: the full mapping does not fit", "250 kbit/s"),
            case("skipped", "<skipped/>", "ideal: never ran"),
        )
    )
    summary.main(["test-summary.py", str(tmp_path), "--requirements", str(tmp_path / "none.toml")])
    out = capsys.readouterr().out.splitlines()
    at = out.index("    3 scenarios on the timed bus (1 Mbit/s 2, 250 kbit/s 1)")
    assert out[at + 1 : at + 3] == [
        "    2 scenarios on the ideal bus, which carries any load:",
        "        2 the full mapping does not fit",
    ]
    assert not any("never ran" in line for line in out)
