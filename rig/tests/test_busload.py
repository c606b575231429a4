"""Bus load: frame bit counts and loads against values computed by hand (see hilrig.busload)."""

from __future__ import annotations

import argparse
import io
from pathlib import Path

import pytest

from boardproto import load_table
from boardproto.cia301 import SYNC_COB_ID, FunctionCode, cob_id, heartbeat_cob_id
from hilrig.busload import (
    STANDARD_BITRATES,
    Traffic,
    add_bus_load_command,
    bus_load,
    frame_bits_nominal,
    frame_bits_worst_case,
    lockstep_traffic,
    report,
    run_bus_load,
    stuff_bits_worst_case,
)

# A node with two RPDOs (one disabled), three TPDOs of transmission types 1, 10 and 254, and a
# 100 ms heartbeat. Every number in the tests below is computed by hand from it.
NODE_ID = 0x10
TABLE = f"""\
[node]
device_type = 0
vendor_id = 1
product_code = 2
revision = 3
device_name = "n"
hardware_version = "h"
software_version = "s"
default_node_id = 0x{NODE_ID:02X}
heartbeat_ms = 100
error_history_length = 4

[[field]]
name = "position"
index = 0x2000
unit = "rad"
kind = "sensor"
access = "ro"
min = -1.0
max = 1.0
default = 0.0
stored = false
description = "p"

[[field]]
name = "setpoint"
index = 0x2400
unit = "rad"
kind = "command"
access = "rw"
min = -1.0
max = 1.0
default = 0.0
stored = false
description = "s"

[[hil_input]]
name = "encoder"
index = 0x3000
type = "unsigned16"
min = 0
max = 65535
unit = "count"
description = "e"

[[hil_output]]
name = "duty"
index = 0x3100
type = "integer16"
min = -10000
max = 10000
unit = "0.01%"
description = "d"

[pdo]
rpdo_slots = 2
tpdo_slots = 3

[[rpdo]]
number = 1
transmission_type = 255
map = ["encoder", "setpoint"]

[[rpdo]]
number = 2
enabled = false
transmission_type = 255
map = ["setpoint"]

[[tpdo]]
number = 1
transmission_type = 1
map = ["duty"]

[[tpdo]]
number = 2
transmission_type = 10
map = ["position", "setpoint"]

[[tpdo]]
number = 3
transmission_type = 254
inhibit_time_100us = 50
map = ["position"]
"""


@pytest.mark.parametrize(
    ("data_bytes", "nominal", "stuff", "worst"),
    [
        # 47 + 8n;  floor((34 + 8n - 1) / 4)
        (0, 47, 8, 55),
        (1, 55, 10, 65),
        (2, 63, 12, 75),
        (3, 71, 14, 85),
        (4, 79, 16, 95),
        (6, 95, 20, 115),
        (8, 111, 24, 135),
    ],
)
def test_frame_bits_match_the_hand_computed_values(
    data_bytes: int, nominal: int, stuff: int, worst: int
) -> None:
    assert frame_bits_nominal(data_bytes) == nominal
    assert stuff_bits_worst_case(data_bytes) == stuff
    assert frame_bits_worst_case(data_bytes) == worst


@pytest.mark.parametrize("data_bytes", [-1, 9])
def test_refuses_lengths_a_classic_frame_cannot_have(data_bytes: int) -> None:
    with pytest.raises(ValueError, match=r"0\.\.8 data bytes"):
        frame_bits_nominal(data_bytes)


def test_one_eight_byte_frame_per_millisecond_on_1_mbit() -> None:
    load = bus_load(
        [Traffic("RPDO1", cob_id(FunctionCode.RPDO1, NODE_ID), 8, 1000.0, True)],
        rate_hz=1000,
        bitrate=1_000_000,
    )
    assert load.nominal == pytest.approx(0.111)
    assert load.worst_case == pytest.approx(0.135)
    assert load.peak_cycle_worst_case == pytest.approx(0.135)
    assert not load.warning


def test_load_scales_inversely_with_the_bitrate() -> None:
    traffic = [Traffic("SYNC", SYNC_COB_ID, 1, 1000.0, True)]
    loads = [bus_load(traffic, 1000, rate).worst_case for rate in STANDARD_BITRATES]
    assert loads == pytest.approx([65_000 / 125_000, 65_000 / 250_000, 65_000 / 500_000, 0.065])


@pytest.fixture
def table_path(tmp_path: Path) -> Path:
    path = tmp_path / "board.toml"
    path.write_text(TABLE)
    return path


def test_lockstep_traffic_follows_the_pdo_layout(table_path: Path) -> None:
    traffic = {t.name: t for t in lockstep_traffic(load_table(table_path), rate_hz=1000)}
    # RPDO2 is disabled: the rig does not send it.
    assert list(traffic) == ["RPDO1", "SYNC", "TPDO1", "TPDO2", "TPDO3", "heartbeat"]
    assert (traffic["RPDO1"].can_id, traffic["RPDO1"].data_bytes, traffic["RPDO1"].per_second) == (
        cob_id(FunctionCode.RPDO1, NODE_ID),
        6,  # unsigned16 + REAL32
        1000,
    )
    assert (traffic["SYNC"].can_id, traffic["SYNC"].data_bytes) == (SYNC_COB_ID, 1)
    assert (traffic["TPDO1"].data_bytes, traffic["TPDO1"].per_second) == (2, 1000)
    assert (traffic["TPDO2"].data_bytes, traffic["TPDO2"].per_second) == (8, 100)  # every 10th SYNC
    # Event driven: once per cycle at most, and the 5 ms inhibit time allows only 200/s.
    assert (traffic["TPDO3"].data_bytes, traffic["TPDO3"].per_second) == (4, 200)
    assert (traffic["heartbeat"].can_id, traffic["heartbeat"].per_second) == (heartbeat_cob_id(NODE_ID), 10)


def test_lockstep_load_of_the_hand_computed_table(table_path: Path) -> None:
    traffic = lockstep_traffic(load_table(table_path), rate_hz=1000)
    load = bus_load(traffic, rate_hz=1000, bitrate=500_000)
    # bits/s nominal: RPDO1 95*1000 + SYNC 55*1000 + TPDO1 63*1000 + TPDO2 111*100
    #                 + TPDO3 79*200 + heartbeat 55*10 = 240_450
    assert load.nominal == pytest.approx(240_450 / 500_000)
    # worst case:     115*1000 + 65*1000 + 75*1000 + 135*100 + 95*200 + 65*10 = 288_150
    assert load.worst_case == pytest.approx(288_150 / 500_000)
    # busiest cycle: every frame once = 115 + 65 + 75 + 135 + 95 + 65 = 550 bits in 1 ms
    assert load.peak_cycle_worst_case == pytest.approx(550 * 1000 / 500_000)
    assert load.warning  # 110 % in the busiest cycle
    assert not bus_load(traffic, rate_hz=1000, bitrate=1_000_000).warning  # 28.8 %, 55 %


def test_acyclic_synchronous_tpdo_counts_every_sync(table_path: Path) -> None:
    table_path.write_text(TABLE.replace("transmission_type = 10", "transmission_type = 0"))
    traffic = {t.name: t for t in lockstep_traffic(load_table(table_path), rate_hz=500)}
    assert traffic["TPDO2"].per_second == 500


def test_report_warns_above_70_percent_only(table_path: Path) -> None:
    traffic = lockstep_traffic(load_table(table_path), rate_hz=1000)
    out = io.StringIO()
    loads = report(traffic, 1000, [250_000, 1_000_000], out)
    text = out.getvalue()
    warnings = [line for line in text.splitlines() if line.startswith("WARNING")]
    assert [load.warning for load in loads] == [True, False]
    assert len(warnings) == 1 and "250 kbit/s" in warnings[0], text
    assert "115.3 %" in text  # 288_150 / 250_000 worst case


def _parse(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="hilrig")
    add_bus_load_command(parser.add_subparsers(dest="command", required=True))
    return parser.parse_args(argv)


def test_command_prints_a_row_per_bitrate(table_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    args = _parse(["bus-load", "--table", str(table_path), "--rate-hz", "100", "--bitrate", "125k"])
    assert args.run(args) == 0
    out = capsys.readouterr().out
    assert "125 kbit/s" in out and "250 kbit/s" not in out
    assert "WARNING" not in out  # 100 Hz: 37_000 bit/s = 29.6 %, busiest cycle 44 %


def test_command_defaults_to_all_four_bitrates(table_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    args = _parse(["bus-load", "--table", str(table_path)])
    assert args.rate_hz == 1000
    assert run_bus_load(args) == 0
    out = capsys.readouterr().out
    for label in ("125 kbit/s", "250 kbit/s", "500 kbit/s", "1 Mbit/s"):
        assert label in out


def test_command_reports_a_bad_table_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[node\n")
    args = _parse(["bus-load", "--table", str(bad)])
    assert run_bus_load(args) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(bad) in err


@pytest.mark.parametrize("argv", [["--bitrate", "fast"], ["--rate-hz", "0"], ["--node-id", "200"]])
def test_command_refuses_bad_options(argv: list[str]) -> None:
    with pytest.raises(SystemExit) as exit_:
        _parse(["bus-load", *argv])
    assert exit_.value.code == 2
