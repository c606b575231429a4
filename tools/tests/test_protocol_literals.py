"""The tree types no protocol value by hand: COB-ID bases, SDO abort codes, fault
bits, control-mode numbers and EMCY codes live in boardproto.cia301 and protocol/board.toml; the
rig, scenarios and tools import them, the firmware includes the headers generated from them. The
lint's own rules are checked on small examples, so it cannot pass by finding nothing."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import pytest


def _load_lint() -> ModuleType:
    path = Path(__file__).resolve().parent.parent / "protocol_literals.py"
    spec = importlib.util.spec_from_file_location("protocol_literals", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["protocol_literals"] = module
    spec.loader.exec_module(module)
    return module


lint = _load_lint()


def findings_in(tmp_path: Path, source: str) -> list[str]:
    path = tmp_path / "example.py"
    path.write_text(source)
    return [f"{f.text}: {f.why}" for f in lint.scan_file(path)]


def test_the_tree_types_no_protocol_value_by_hand() -> None:
    files = lint.scanned_files()
    assert len(files) > 50, f"expected the rig, scenarios and tools, found {len(files)} files"
    tops = {f.relative_to(lint.REPO).parts[0] for f in files}
    assert tops == {"firmware", "protocol", "rig", "tests", "tools"}
    assert lint.REPO / "firmware" / "canopen" / "Node.cpp" in files
    assert lint.REPO / "protocol" / "boardproto" / "eds.py" in files
    assert lint.REPO / "protocol" / "boardproto" / "cia301.py" not in files  # the home
    findings = lint.scan(files)
    assert not findings, "protocol values typed by hand (python tools/protocol_literals.py):\n" + "\n".join(
        map(str, findings)
    )


@pytest.mark.parametrize(
    ("source", "expected"),
    [
        ("SYNC = 0x080\n", "0x080"),
        ("heartbeat = 0x700 + node_id\n", "0x700"),
        ("tpdo1_of_node_16 = 0x190\n", "0x190"),
        ("LSS_REQUEST = 0x7E5\n", "0x7E5"),
        ("if answer[0] == 0x80: pass\n", "0x80"),
        ("EMCY_STALE = 0x5000\n", "0x5000"),
        ('rig.set("control_mode", 1)\n', "1"),
        ('rig.set("control_mode", 0)\n', "0"),
        ("VELOCITY_MODE = 1.0\n", "1.0"),
        ("assert control_mode == 2\n", "2"),
        ("COMMAND_WATCHDOG_BIT = 1 << 4\n", "4"),
        ("STALE_FLAGS = 0b11\n", "0b11"),
        ('assert rig.field("fault_flags") == 16\n', "16"),
        ('assert decoded == {"safe_state": 0.0, "fault_flags": 3.0}\n', "3.0"),
        ("ok = int(fault_flags) & 3\n", "3"),
    ],
)
def test_a_typed_protocol_value_is_found(tmp_path: Path, source: str, expected: str) -> None:
    found = findings_in(tmp_path, source)
    assert any(f.startswith(f"{expected}: ") for f in found), found


@pytest.mark.parametrize(
    "source",
    [
        "SYNC = SYNC_COB_ID\n",
        'rig.set("control_mode", ControlMode.VELOCITY)\n',
        'rig.set("velocity_setpoint", 2.0)\n',
        'assert rig.field("fault_flags") == 0\n',  # no fault is not a bit
        "run(cycles=1000, fault_interval=10_000)\n",
        "frame_id = 0x7C1  # no service's identifier\n",
        "index = 0x2000 + 0x10\n",  # an object index, not a COB-ID
        'scale = _rms(rig, ControlMode.TORQUE, "torque_setpoint", 1.0)\n',
        "ascii = byte < 0x80  # protocol-literal: a 7-bit ASCII limit, not SYNC\n",
        'assert len(trace[paths["control_mode"]]) >= 2\n',  # a count, not a mode
        'assert decoded == {"safe_state": 1.0, "fault_flags": 0.0}\n',  # 1.0 is not a fault bit
    ],
)
def test_a_named_or_unrelated_value_is_not_found(tmp_path: Path, source: str) -> None:
    assert findings_in(tmp_path, source) == []


def test_a_deliberate_literal_needs_a_reason(tmp_path: Path) -> None:
    found = findings_in(tmp_path, "SYNC = 0x080  # protocol-literal:\n")
    assert len(found) == 1 and "gives no reason" in found[0], found


def test_the_command_line_lists_findings_and_fails(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad.py"
    bad.write_text("HEARTBEAT = 0x700\n")
    assert lint.main([str(bad)]) == 1
    out, err = capsys.readouterr()
    assert f"{bad}:1: '0x700'" in out and "boardproto.cia301" in out
    assert "1 protocol value(s) typed by hand" in err
    good = tmp_path / "good.py"
    good.write_text("from boardproto.cia301 import heartbeat_cob_id\n")
    assert lint.main([str(good)]) == 0


def cpp_findings_in(tmp_path: Path, source: str) -> list[str]:
    path = tmp_path / "example.cpp"
    path.write_text(source)
    return [f"{f.text}: {f.why}" for f in lint.scan_file(path)]


@pytest.mark.parametrize(
    ("source", "expected"),
    [
        ("constexpr std::uint32_t kSdoRequestBase = 0x600;\n", "0x600"),
        ("send(0x580u + node_id_, response);\n", "0x580u"),
        ("sync_cob_id_ = node + 0x80;\n", "0x80"),
        ("if (frame.id == 0x190) {}\n", "0x190"),
        ("if (frame.id == 0x7E4) {}\n", "0x7E4"),
        ("return SdoAbort{0x0609'0031u};\n", "0x0609'0031u"),
        ("constexpr auto kReadOnly = 0x06010002;\n", "0x06010002"),
    ],
)
def test_a_typed_cia301_value_is_found_in_cpp(tmp_path: Path, source: str, expected: str) -> None:
    found = cpp_findings_in(tmp_path, source)
    assert any(f.startswith(f"{expected}: ") and "board/cia301.hpp" in f for f in found), found


@pytest.mark.parametrize(
    "source",
    [
        "send(cia301::cob_id(cia301::FunctionCode::SdoResponse, node_id_), response);\n",
        "if (request[0] == 0x80) return abort();  // a command specifier, not SYNC\n",
        "if (++count == 0x80) ++totals;\n",
        "// answered on 0x580+id with 0x06090031\n",
        "/* 0x600 + id,\n   0x700 + id */ int x = 0;\n",
        'const char* text = "0x0609\'0031 on 0x600";\n',
        "const char c = '\\x80';\n",
        "constexpr std::uint32_t kFree = 0x7E0;  // no service's identifier\n",
        "constexpr std::uint32_t kOther = 0x555;  // protocol-literal: any free identifier\n",
        "constexpr std::uint32_t kMask = 0x7FF'F800u;\n",
    ],
)
def test_a_named_or_unrelated_cpp_value_is_not_found(tmp_path: Path, source: str) -> None:
    assert cpp_findings_in(tmp_path, source) == []


def test_a_deliberate_cpp_literal_needs_a_reason(tmp_path: Path) -> None:
    found = cpp_findings_in(tmp_path, "auto id = 0x600 + 1;  // protocol-literal:\n")
    assert len(found) == 1 and "gives no reason" in found[0], found


def test_an_abort_code_in_python_is_found(tmp_path: Path) -> None:
    found = findings_in(tmp_path, "READ_ONLY = 0x0601_0002\n")
    assert found == ["0x0601_0002: an SDO abort code: use boardproto.cia301.SdoAbortCode"]


def test_which_rules_apply_depends_on_the_folder() -> None:
    """The conformance scenarios spell the spec's abort codes on purpose; protocol/ defines the
    named values the fault and control-mode rules are about."""
    scenarios = lint._rules_for(lint.REPO / "tests" / "test_conformance_cia301.py")
    assert not scenarios.sdo_abort_codes and scenarios.named_values
    protocol = lint._rules_for(lint.REPO / "protocol" / "tests" / "test_protocol_dbc.py")
    assert protocol.sdo_abort_codes and not protocol.named_values
    firmware = lint._rules_for(lint.REPO / "firmware" / "canopen" / "Node.cpp")
    assert firmware.sdo_abort_codes
