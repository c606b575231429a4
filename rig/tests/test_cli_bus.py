"""The bus options of every `hilrig` command follow python-can's conventions: defaults from
python-can's configuration (~/.canrc, CAN_INTERFACE, CAN_CHANNEL, CAN_BITRATE, CAN_CONFIG),
socketcan vcan0 only when nothing is configured; one bit rate parser; `--bus-kwargs` and
`--filter` spelt as python-can's tools spell them; an interface that cannot work here is a
usage error that says what to install."""

from __future__ import annotations

import argparse
import json
from collections.abc import Iterator
from pathlib import Path

import can
import pytest

from boardproto.cia301 import (
    FUNCTION_CODE_MASK,
    STANDARD_ID_MASK,
    SYNC_COB_ID,
    FunctionCode,
    cob_id,
    heartbeat_cob_id,
)
from hilrig.cli import main
from hilrig.cli.common import (
    CanFilter,
    UsageError,
    add_bus_options,
    bitrate,
    bus_config,
    bus_kwarg,
    can_filter,
)
from hilrig.session.fake_node import FakeJointNode
from hilrig.table import RigTable

NODE_ID = RigTable.load().board.node.default_node_id
DEFAULT_KP = RigTable.load().field("velocity_kp").default


@pytest.fixture
def no_can_config(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Iterator[Path]:
    """python-can's configuration emptied: no environment variables, no can.rc, and the config
    files looked for only at the returned path (absent until a test writes it)."""
    for name in ("CAN_INTERFACE", "CAN_CHANNEL", "CAN_BITRATE", "CAN_CONFIG"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setattr(can, "rc", {})
    canrc = tmp_path / ".canrc"
    monkeypatch.setattr(can.util, "CONFIG_FILES", [str(canrc)])
    yield canrc


def parsed(*argv: str, filters: bool = True) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_bus_options(parser, filters=filters)
    return parser.parse_args(list(argv))


# --- argument types ---------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("text", "expected"),
    [("125000", 125_000), ("500k", 500_000), ("500K", 500_000), ("1M", 1_000_000), ("2.5M", 2_500_000)],
)
def test_a_bit_rate_takes_k_and_m(text: str, expected: int) -> None:
    assert bitrate(text) == expected


@pytest.mark.parametrize("text", ["fast", "0", "-500k", "1.5", "500kk", "k", ""])
def test_a_bad_bit_rate_is_refused(text: str) -> None:
    with pytest.raises(argparse.ArgumentTypeError, match="like 125000, 500k or 1M"):
        bitrate(text)


def test_bus_kwargs_are_typed_as_python_cans_tools_type_them() -> None:
    assert bus_kwarg("serial=1234") == ("serial", 1234)
    assert bus_kwarg("app_name=MyApp") == ("app_name", "MyApp")
    assert bus_kwarg("receive-own-messages=True") == ("receive_own_messages", True)
    assert bus_kwarg("timeout=0.5") == ("timeout", 0.5)
    for bad in ("=1", "serial", "1x=2"):
        with pytest.raises(argparse.ArgumentTypeError, match="expected KEY=VALUE"):
            bus_kwarg(bad)


def test_filters_are_python_cans_spelling() -> None:
    tpdo1 = can_filter(f"{FunctionCode.TPDO1:X}:{FUNCTION_CODE_MASK:X}")
    assert tpdo1 == CanFilter(int(FunctionCode.TPDO1), FUNCTION_CODE_MASK)
    assert tpdo1.keeps(cob_id(FunctionCode.TPDO1, NODE_ID))
    assert not tpdo1.keeps(heartbeat_cob_id(NODE_ID))
    not_heartbeats = can_filter(f"0x{FunctionCode.HEARTBEAT:X}~{FUNCTION_CODE_MASK:X}")  # 0x prefix welcome
    assert not_heartbeats.inverted
    assert not not_heartbeats.keeps(heartbeat_cob_id(NODE_ID))
    assert not_heartbeats.keeps(cob_id(FunctionCode.TPDO1, NODE_ID))
    for bad in ("180", "xyz:7FF", "180:", "20000000:7FF"):
        with pytest.raises(argparse.ArgumentTypeError, match="CAN_ID:MASK"):
            can_filter(bad)


# --- where the bus comes from -------------------------------------------------------------------
def test_with_nothing_configured_the_bus_is_socketcan_vcan0(no_can_config: Path) -> None:
    config = bus_config(parsed())
    assert (config["interface"], config["channel"]) == ("socketcan", "vcan0")
    assert "bitrate" not in config


def test_python_cans_environment_variables_are_the_default(
    no_can_config: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("CAN_INTERFACE", "pcan")
    monkeypatch.setenv("CAN_CHANNEL", "PCAN_USBBUS2")
    monkeypatch.setenv("CAN_BITRATE", "500k")  # python-can passes it on as text: hilrig parses it
    monkeypatch.setenv("CAN_CONFIG", json.dumps({"fd": True, "data_bitrate": 2_000_000}))
    config = bus_config(parsed())
    assert config["interface"] == "pcan" and config["channel"] == "PCAN_USBBUS2"
    assert (config["bitrate"], config["fd"], config["data_bitrate"]) == (500_000, True, 2_000_000)
    # the command line wins over the configuration
    config = bus_config(parsed("-i", "kvaser", "-c", "0", "-b", "250k"))
    assert (config["interface"], config["channel"], config["bitrate"]) == ("kvaser", 0, 250_000)


def test_a_canrc_file_is_the_default(no_can_config: Path) -> None:
    no_can_config.write_text("[default]\ninterface = slcan\nchannel = /dev/ttyACM0\nbitrate = 1M\n")
    config = bus_config(parsed())
    assert (config["interface"], config["channel"], config["bitrate"]) == ("slcan", "/dev/ttyACM0", 1_000_000)


def test_only_a_channel_configured_keeps_socketcan_with_that_channel(
    no_can_config: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("CAN_CHANNEL", "can1")
    assert bus_config(parsed())["channel"] == "can1"
    assert bus_config(parsed())["interface"] == "socketcan"


def test_fd_kwargs_and_filters_reach_can_bus(no_can_config: Path) -> None:
    tpdo1, heartbeat = int(FunctionCode.TPDO1), int(FunctionCode.HEARTBEAT)
    keep = [f"{tpdo1:X}:{FUNCTION_CODE_MASK:X}", f"{heartbeat:X}:{FUNCTION_CODE_MASK:X}"]
    config = bus_config(parsed("--data-bitrate", "2M", "--bus-kwargs", "serial=1234", "--filter", *keep))
    assert (config["fd"], config["data_bitrate"], config["serial"]) == (True, 2_000_000, 1234)
    assert config["can_filters"] == [
        {"can_id": tpdo1, "can_mask": FUNCTION_CODE_MASK},
        {"can_id": heartbeat, "can_mask": FUNCTION_CODE_MASK},
    ]
    # an inverted filter is applied by the command, so none go to the bus (it would drop what it keeps)
    assert "can_filters" not in bus_config(parsed("--filter", keep[0], keep[1].replace(":", "~")))


def test_an_unknown_configured_interface_is_a_usage_error(
    no_can_config: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("CAN_INTERFACE", "socketcn")
    with pytest.raises(UsageError, match=r"python-can's configuration .* is unusable: .*socketcn"):
        bus_config(parsed())
    monkeypatch.setenv("CAN_INTERFACE", "virtual")
    monkeypatch.setenv("CAN_BITRATE", "fast")
    with pytest.raises(UsageError, match="bitrate: expected a bit rate"):
        bus_config(parsed())


def test_get_talks_to_the_bus_python_can_is_configured_for(
    capsys: pytest.CaptureFixture[str],
    no_can_config: Path,
    monkeypatch: pytest.MonkeyPatch,
    fake: FakeJointNode,
    channel: str,
) -> None:
    monkeypatch.setenv("CAN_INTERFACE", "virtual")
    monkeypatch.setenv("CAN_CHANNEL", channel)
    code = main(["get", "velocity_kp", "--sdo-timeout", "2"])
    out, err = capsys.readouterr()
    assert (code, err) == (0, "")
    assert out.split()[:3] == ["velocity_kp", "=", f"{DEFAULT_KP:g}"]


# --- an interface that cannot work here ---------------------------------------------------------
def test_a_missing_package_says_what_to_install(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    def no_pyserial(**kwargs: object) -> can.BusABC:  # what python-can's slcan says without pyserial
        raise can.CanInterfaceNotImplementedError("The serial module is not installed")

    monkeypatch.setattr(can, "Bus", no_pyserial)
    code = main(["get", "velocity_kp", "-i", "slcan", "-c", "/dev/ttyACM0"])
    out, err = capsys.readouterr()
    assert (code, out) == (2, "")
    assert err == (
        "hilrig get: error: cannot use the slcan interface: it needs the pyserial package, which is "
        "not installed: pip install pyserial (or pip install 'python-can[serial]')\n"
    )


def test_an_interface_for_another_platform_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    # python-can's Vector interface needs Windows; on Windows, the XL driver library
    code = main(["scan", "-i", "vector", "-c", "0"])
    _, err = capsys.readouterr()
    assert err.count("\n") == 1, err
    assert (code, err.startswith("hilrig scan: error: cannot use the vector interface: ")) == (2, True), err


def test_an_interface_that_wants_other_options_points_at_bus_kwargs(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code = main(["scan", "-i", "socketcand", "-c", "can0"])  # socketcand wants host= and port=
    _, err = capsys.readouterr()
    assert code == 2
    assert err.startswith("hilrig scan: error: the socketcand interface refused its options: ")
    assert "--bus-kwargs KEY=VALUE" in err and err.count("\n") == 1


# --- --filter where a command receives ----------------------------------------------------------
def test_record_keeps_only_the_filtered_frames(
    capsys: pytest.CaptureFixture[str], fake: FakeJointNode, channel: str, tmp_path: Path
) -> None:
    log = tmp_path / "tpdo1.log"
    tpdo1 = cob_id(FunctionCode.TPDO1, NODE_ID)
    argv = ["--nmt-start", "--sync-period-ms", "5", "-i", "virtual", "-c", channel]
    keep = f"{tpdo1:X}:{STANDARD_ID_MASK:X}"
    code = main(["record", str(log), "--count", "5", "--filter", keep, *argv])
    _, err = capsys.readouterr()
    assert code == 0, err
    assert f"frames {keep} ->" in err
    assert [m.arbitration_id for m in can.LogReader(str(log))] == [tpdo1] * 5
    # inverted: everything but SYNC (the command's own, recorded otherwise)
    log = tmp_path / "rest.log"
    code = main(
        ["record", str(log), "--count", "20", "--filter", f"{SYNC_COB_ID:X}~{STANDARD_ID_MASK:X}", *argv]
    )
    _, err = capsys.readouterr()
    assert code == 0, err
    ids = [m.arbitration_id for m in can.LogReader(str(log))]
    assert tpdo1 in ids and SYNC_COB_ID not in ids and len(ids) == 20
