"""Bus load: frame bit counts and loads against values computed by hand (see hilrig.apps.busload)."""

from __future__ import annotations

import io
from pathlib import Path

import pytest

from boardproto import BoardTable, load_table
from boardproto.cia301 import SYNC_COB_ID, FunctionCode, cob_id, heartbeat_cob_id
from hilrig.apps.busload import (
    STANDARD_BITRATES,
    BusRates,
    Traffic,
    bus_load,
    fd_data_length,
    fd_frame_bits,
    frame_bits_nominal,
    frame_bits_worst_case,
    highest_rate_hz,
    lockstep_traffic,
    report,
    robot_load_line,
    stuff_bits_worst_case,
)
from hilrig.cli import main
from hilrig.table import DEFAULT_TABLE_PATH

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
heartbeat_consumers = 1

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


def test_report_warns_above_70_percent_and_flags_above_100(table_path: Path) -> None:
    traffic = lockstep_traffic(load_table(table_path), rate_hz=1000)
    out = io.StringIO()
    loads = report(traffic, 1000, [250_000, 750_000, 1_000_000], out)
    text = out.getvalue()
    lines = [line for line in text.splitlines() if line.startswith(("WARNING", "OVERLOAD"))]
    assert [(load.warning, load.overloaded) for load in loads] == [
        (True, True),
        (True, False),
        (False, False),
    ]
    # 250 kbit/s: 288_150 / 250_000 = 115.3 % worst case; 750 kbit/s: busiest cycle 550_000 / 750_000
    assert [line.split(":")[:2] for line in lines] == [
        ["OVERLOAD", " 250 kbit/s"],
        ["WARNING", " 750 kbit/s"],
    ]
    assert "115.3 %" in lines[0] and "73.3 %" in lines[1], text


# --- a robot: identical modules on one bus -----------------------------------------------------
MASTER_HEARTBEAT_COB_ID = 0x77F  # protocol-literal: by hand, 0x700 + the master's default node id 0x7F


def test_robot_traffic_has_one_row_per_kind_counting_every_module(table_path: Path) -> None:
    traffic = lockstep_traffic(load_table(table_path), 1000, node_ids=[1, 2], master_heartbeat_ms=20)
    rows = {t.name: (t.count, t.can_id, t.highest_can_id, t.per_second) for t in traffic}
    assert rows == {
        "RPDO1": (2, 0x201, 0x202, 1000),  # protocol-literal: by hand
        "SYNC": (1, SYNC_COB_ID, None, 1000),  # one SYNC for every module
        "TPDO1": (2, 0x181, 0x182, 1000),  # protocol-literal: by hand
        "TPDO2": (2, 0x281, 0x282, 100),  # protocol-literal: by hand
        "TPDO3": (2, 0x381, 0x382, 200),  # protocol-literal: by hand
        "heartbeat": (2, 0x701, 0x702, 10),  # protocol-literal: by hand
        "master heartbeat": (1, MASTER_HEARTBEAT_COB_ID, None, 50),  # every 20 ms
    }
    assert list(rows) == ["RPDO1", "SYNC", "TPDO1", "TPDO2", "TPDO3", "heartbeat", "master heartbeat"]


def test_robot_load_of_two_modules_by_hand(table_path: Path) -> None:
    traffic = lockstep_traffic(load_table(table_path), 1000, node_ids=[1, 2], master_heartbeat_ms=20)
    load = bus_load(traffic, rate_hz=1000, bitrate=1_000_000)
    # Per module as in test_lockstep_load_of_the_hand_computed_table without its SYNC:
    #   nominal 95*1000 + 63*1000 + 111*100 + 79*200 + 55*10 = 185_450 bit/s
    #   worst   115*1000 + 75*1000 + 135*100 + 95*200 + 65*10 = 223_150 bit/s
    # two modules, one SYNC (55 / 65 bits x 1000) and the master heartbeat (55 / 65 bits x 50):
    #   nominal 2*185_450 + 55_000 + 2_750 = 428_650; worst 2*223_150 + 65_000 + 3_250 = 514_550
    assert load.nominal == pytest.approx(0.428_650)
    assert load.worst_case == pytest.approx(0.514_550)
    # busiest cycle: per module 115 + 75 + 135 + 95 + 65 = 485 bits; 2*485 + SYNC 65 + master 65
    # = 1100 bits in 1 ms
    assert load.peak_cycle_worst_case == pytest.approx(1.1)
    no_master = lockstep_traffic(load_table(table_path), 1000, node_ids=[1, 2], master_heartbeat_ms=0)
    assert "master heartbeat" not in [t.name for t in no_master]
    assert bus_load(no_master, 1000, 1_000_000).worst_case == pytest.approx(0.511_300)  # - 3_250


def test_one_module_robot_is_the_single_node_plus_the_master_heartbeat(table_path: Path) -> None:
    table = load_table(table_path)
    robot = lockstep_traffic(table, 1000, node_ids=[NODE_ID], master_heartbeat_ms=20)
    assert robot[:-1] == lockstep_traffic(table, 1000)
    assert (robot[-1].name, robot[-1].can_id) == ("master heartbeat", MASTER_HEARTBEAT_COB_ID)


def test_report_prints_a_row_per_kind_with_its_count_and_cob_id_range(table_path: Path) -> None:
    traffic = lockstep_traffic(load_table(table_path), 1000, node_ids=[1, 2], master_heartbeat_ms=20)
    out = io.StringIO()
    report(traffic, 1000, [1_000_000], out)
    frame_rows = [line.split() for line in out.getvalue().split("\n\n")[0].splitlines()[1:]]
    assert [row[:3] for row in frame_rows] == [
        ["RPDO1", "x2", "0x201..0x202"],
        ["SYNC", "0x080", "1"],
        ["TPDO1", "x2", "0x181..0x182"],
        ["TPDO2", "x2", "0x281..0x282"],
        ["TPDO3", "x2", "0x381..0x382"],
        ["heartbeat", "x2", "0x701..0x702"],
        ["master", "heartbeat", "0x77F"],
    ]
    load_row = next(line for line in out.getvalue().splitlines() if line.startswith("1 Mbit/s"))
    assert load_row.split() == [
        "1",
        "Mbit/s",
        "42.9",
        "%",
        "51.5",
        "%",
        "110.0",
        "%",
    ]  # test_robot_load_of_two_modules_by_hand


def test_robot_refuses_colliding_cob_ids() -> None:
    table = load_table(DEFAULT_TABLE_PATH)
    # The default layout puts TPDO5 of node 1 on 0x1C1 = 0x180 + 65: TPDO1 of node 65.
    with pytest.raises(ValueError, match="COB-ID 0x1C1 of TPDO1 of node 65 is also that of TPDO5 of node 1"):
        lockstep_traffic(table, 100, node_ids=[1, 65])
    with pytest.raises(ValueError, match="master's"):
        lockstep_traffic(table, 100, node_ids=[1, 0x7F], master_heartbeat_ms=20)
    with pytest.raises(ValueError, match="not both"):
        lockstep_traffic(table, 100, 1, node_ids=[1, 2])


# --- highest_rate_hz ---------------------------------------------------------------------------
def warning_at(
    table: BoardTable,
    rate_hz: float,
    bitrate: int,
    node_ids: list[int] | None = None,
    master_heartbeat_ms: int = 0,
) -> bool:
    traffic = lockstep_traffic(table, rate_hz, node_ids=node_ids, master_heartbeat_ms=master_heartbeat_ms)
    return bus_load(traffic, rate_hz, bitrate).warning


def test_highest_rate_when_the_busiest_cycle_binds(table_path: Path) -> None:
    table = load_table(table_path)
    # busiest cycle 550 bits (see above): 0.7 * 500_000 / 550 = 636.36 Hz; the average there is
    # 268.5 * 636 + 95 * 200 + 650 = 190_416 bit/s, 38 %: not the limit.
    assert highest_rate_hz(table, 500_000) == 636.3
    # two modules and the master: 1100 bits, 0.7 * 500_000 / 1100 = 318.18 Hz
    modules = [1, 2]
    assert highest_rate_hz(table, 500_000, node_ids=modules, master_heartbeat_ms=20) == 318.1
    for bitrate in STANDARD_BITRATES:
        rate = highest_rate_hz(table, bitrate, node_ids=modules, master_heartbeat_ms=20)
        assert not warning_at(table, rate, bitrate, modules, 20)
        assert warning_at(table, rate + 0.1, bitrate, modules, 20)
        assert warning_at(table, rate + 1, bitrate, modules, 20)


def test_highest_rate_when_the_average_binds(table_path: Path) -> None:
    # A 1 ms event timer sends TPDO3 (4 bytes, 95 bits) 1000 times a second whatever the rate:
    # average 115r + 65r + 75r + 13.5r + 95_000 + 650 = 268.5r + 95_650 <= 175_000 at 250 kbit/s
    # -> r <= 295.53 Hz, below the busiest cycle's 0.7 * 250_000 / 550 = 318.18 Hz.
    table_path.write_text(
        TABLE.replace("inhibit_time_100us = 50", "inhibit_time_100us = 50\nevent_timer_ms = 1")
    )
    table = load_table(table_path)
    rate = highest_rate_hz(table, 250_000)
    assert rate == 295.5
    assert not warning_at(table, rate, 250_000) and warning_at(table, rate + 0.1, 250_000)
    # At 125 kbit/s that TPDO alone takes 95_650 / 125_000 = 76.5 %: no rate fits.
    assert highest_rate_hz(table, 125_000) == 0.0
    assert highest_rate_hz(table, 125_000, max_load=0.9) > 0


# --- CAN FD: every number below by hand from the formulas in hilrig.apps.busload's docstring ----------
@pytest.mark.parametrize(
    ("data_bytes", "nominal", "worst"),
    [
        # (30, 5 + 8n + 4 + 17 + 6); worst case: + 3 bits at the nominal rate,
        # + floor((21 + 8n) / 4) - 3 at the data rate
        (0, (30, 32), (33, 34)),  # 5 stuff bits: 3 + 2
        (1, (30, 40), (33, 44)),  # 7: 3 + 4
        (8, (30, 96), (33, 114)),  # 21: 3 + 18
        (9, (30, 128), (33, 154)),  # padded to 12 bytes: 5 + 96 + 4 + 17 + 6; 29 stuff bits
        (20, (30, 197), (33, 239)),  # CRC-21 and 7 fixed stuff bits: 5 + 160 + 4 + 21 + 7; 45
        (64, (30, 549), (33, 679)),  # 5 + 512 + 4 + 21 + 7; 133 stuff bits: 3 + 130
    ],
)
def test_fd_frame_bits_match_the_hand_computed_values(
    data_bytes: int, nominal: tuple[int, int], worst: tuple[int, int]
) -> None:
    assert fd_frame_bits(data_bytes, worst_case=False) == nominal
    assert fd_frame_bits(data_bytes, worst_case=True) == worst


def test_fd_payloads_are_padded_to_a_dlc_length() -> None:
    assert [fd_data_length(n) for n in (0, 8, 9, 13, 17, 33, 49, 64)] == [0, 8, 12, 16, 20, 48, 64, 64]
    with pytest.raises(ValueError, match=r"0\.\.64 data bytes"):
        fd_data_length(65)


def test_an_fd_frame_takes_arbitration_at_the_nominal_rate_and_data_at_the_data_rate() -> None:
    # 8 bytes at 500 kbit/s with a 2 Mbit/s data phase: 30 bits / 500k + 96 bits / 2M = 60 + 48 us;
    # worst case 33 / 500k + 114 / 2M = 66 + 57 us.
    brs = BusRates(500_000, data_bitrate=2_000_000)
    assert brs.frame_seconds(8, worst_case=False) == pytest.approx(108e-6)
    assert brs.frame_seconds(8, worst_case=True) == pytest.approx(123e-6)
    # Without a bit rate switch all 126 (147) bits go at 500 kbit/s: longer than classic (111)
    no_brs = BusRates(500_000, fd=True)
    assert no_brs.frame_seconds(8, worst_case=False) == pytest.approx(126 / 500_000)
    assert no_brs.frame_seconds(8, worst_case=True) == pytest.approx(147 / 500_000)
    assert BusRates(500_000).frame_seconds(8, worst_case=False) == pytest.approx(111 / 500_000)
    assert [r.label for r in (brs, no_brs, BusRates(1_000_000))] == [
        "500 kbit/s + 2 Mbit/s FD",
        "500 kbit/s FD",
        "1 Mbit/s",
    ]


def test_fd_load_of_one_eight_byte_frame_per_millisecond() -> None:
    traffic = [Traffic("RPDO1", cob_id(FunctionCode.RPDO1, NODE_ID), 8, 1000.0, True)]
    load = bus_load(traffic, rate_hz=1000, bitrate=BusRates(500_000, data_bitrate=2_000_000))
    assert load.nominal == pytest.approx(0.108)
    assert load.worst_case == pytest.approx(0.123)
    assert load.peak_cycle_worst_case == pytest.approx(0.123)
    assert load.bitrate == 500_000


# --- the command: `hilrig bus-load` ------------------------------------------------------------
def bus_load_command(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(["bus-load", *argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_command_prints_a_row_per_bitrate(table_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = bus_load_command(
        capsys, "--table", str(table_path), "--rate-hz", "100", "--bitrate", "125k"
    )
    assert (code, err) == (0, "")
    assert "125 kbit/s" in out and "250 kbit/s" not in out
    assert "WARNING" not in out  # 100 Hz: 37_000 bit/s = 29.6 %, busiest cycle 44 %


def test_command_defaults_to_all_four_bitrates(table_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = bus_load_command(capsys, "--table", str(table_path), "--rate-hz", "100")
    assert code == 0
    for label in ("125 kbit/s", "250 kbit/s", "500 kbit/s", "1 Mbit/s"):
        assert label in out


def test_command_without_options_explains_rather_than_fails(capsys: pytest.CaptureFixture[str]) -> None:
    # The board's default mapping at 1 kHz fits no standard bit rate: the survey says so, exit 0.
    code, out, err = bus_load_command(capsys)
    assert (code, err) == (0, "")
    assert out.count("OVERLOAD") == 4
    assert out.splitlines()[-1] == (
        "at 1000 Hz the exchange fits none of these bit rates; give -b BITRATE for the bus you mean "
        "(exit code 1 when it does not fit)"
    )
    code, out, err = bus_load_command(capsys, "--rate-hz", "200")
    assert (code, err) == (0, "")
    assert "the exchange fits 500 kbit/s, 1 Mbit/s; give -b" in out.splitlines()[-1]


def test_command_warns_above_70_percent_with_exit_code_0(
    table_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, err = bus_load_command(capsys, "--table", str(table_path), "-b", "750k")
    assert (code, err) == (0, "")
    warnings = [line for line in out.splitlines() if line.startswith("WARNING")]
    assert len(warnings) == 1 and warnings[0].startswith(
        "WARNING: 750 kbit/s: 38.4 % of the bus (busiest cycle 73.3 %)"
    )


def test_command_fails_above_100_percent_with_one_error_line(
    table_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, err = bus_load_command(capsys, "--table", str(table_path), "-b", "250k", "-b", "1M")
    assert code == 1
    verdicts = [line for line in out.splitlines() if line.startswith(("OVERLOAD", "WARNING"))]
    assert [line.split(" of the bus")[0] for line in verdicts] == ["OVERLOAD: 250 kbit/s: 115.3 %"]
    assert err == (
        "hilrig bus-load: error: at 1000 Hz the exchange does not fit 250 kbit/s (above 100 % of the bus)\n"
    )


def test_command_counts_fd_frames_with_the_data_bitrate(
    table_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # At 500 kbit/s the busiest cycle of classic frames does not fit (110 %); as FD frames with a
    # 2 Mbit/s data phase they do: RPDO1 (6 bytes) 30 + 80 bits, SYNC 30 + 40, TPDO1 (2) 30 + 48,
    # TPDO2 (8) 30 + 96, TPDO3 (4) 30 + 64, heartbeat 30 + 40, at 1000, 1000, 1000, 100, 200, 10 /s.
    code, out, err = bus_load_command(
        capsys, "--table", str(table_path), "-b", "500k", "--data-bitrate", "2M"
    )
    assert (code, err) == (0, "")
    rates = {1000: ("RPDO1", "SYNC", "TPDO1"), 100: ("TPDO2",), 200: ("TPDO3",), 10: ("heartbeat",)}
    data_bits = {"RPDO1": 80, "SYNC": 40, "TPDO1": 48, "TPDO2": 96, "TPDO3": 64, "heartbeat": 40}
    busy_s = sum(
        per_s * (30 / 500_000 + data_bits[name] / 2_000_000)
        for per_s, names in rates.items()
        for name in names
    )
    row = next(line for line in out.splitlines() if line.startswith("500 kbit/s + 2 Mbit/s FD"))
    assert row.split()[6] == f"{100 * busy_s:.1f}", row
    assert "as CAN FD frames" in out.splitlines()[0]
    assert "RPDO1       0x210      6          1                     30+80" in out


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["--bitrate", "fast"], "expected a bit rate in bit/s like 125000, 500k or 1M, got 'fast'"),
        (["--rate-hz", "0"], "expected a positive cycle rate in Hz"),
        (["--node-id", "200"], "expected a node id 1..127"),
        (["--table", "nowhere.toml"], "board table nowhere.toml does not exist"),
        (["-b", "1M", "--data-bitrate", "500k"], "--data-bitrate 500000 is below a --bitrate (1000000)"),
        (["--modules", "0"], "expected a number of modules 1..63 (node ids 1..N), got '0'"),
        (["--modules", "64"], "expected a number of modules 1..63"),
        (["--modules", "eight"], "expected a number of modules 1..63"),
        (
            ["--master-heartbeat-ms", "10"],
            "--master-heartbeat-ms is the robot master's: give it with --modules",
        ),
        (["--modules", "2", "--master-heartbeat-ms", "-5"], "expected a heartbeat period 0..65535 in ms"),
        (["--modules", "2", "--node-id", "3"], "with --modules N the node ids are 1..N"),
    ],
)
def test_command_refuses_bad_options(
    capsys: pytest.CaptureFixture[str], argv: list[str], expected: str
) -> None:
    code, out, err = bus_load_command(capsys, *argv)
    assert (code, out) == (2, "")
    assert expected in err and err.count("\n") == 1, err


def test_command_modules_prints_the_robot_and_its_highest_rates(
    table_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, err = bus_load_command(
        capsys, "--table", str(table_path), "--modules", "2", "-b", "500k", "-b", "1M"
    )
    # at 1000 Hz: busiest cycle 1100 bits (test_robot_load_of_two_modules_by_hand): 220 % of
    # 500 kbit/s, 110 % of 1 Mbit/s
    assert code == 1 and "exchange does not fit 500 kbit/s, 1 Mbit/s" in err
    lines = out.splitlines()
    assert lines[0].startswith(
        "bus load of a robot of 2 modules (node ids 1..2, one SYNC, master heartbeat every 20 ms)"
    )
    assert "RPDO1 x2          0x201..0x202" in out
    # 0.7 * 500_000 / 1100 = 318.18 Hz, 0.7 * 1_000_000 / 1100 = 636.36 Hz
    assert lines[-1] == "highest SYNC rate within 70 % (worst case): 500 kbit/s: 318.1 Hz, 1 Mbit/s: 636.3 Hz"
    code, out, _ = bus_load_command(
        capsys, "--table", str(table_path), "--modules", "2", "--master-heartbeat-ms", "0", "-b", "1M"
    )
    # without the master's heartbeat 1035 bits: 0.7 * 1_000_000 / 1035 = 676.33 Hz
    assert "master heartbeat" not in out.splitlines()[2:] and "no master heartbeat" in out.splitlines()[0]
    assert out.splitlines()[-1].endswith("1 Mbit/s: 676.3 Hz")


def test_command_prints_the_highest_rate_for_one_node_too(
    table_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, _ = bus_load_command(capsys, "--table", str(table_path), "--rate-hz", "100", "-b", "125k")
    # 0.7 * 125_000 / 550 = 159.09 Hz
    assert (
        code == 0
        and out.splitlines()[-1] == "highest SYNC rate within 70 % (worst case): 125 kbit/s: 159.0 Hz"
    )


def test_command_reports_a_bad_table_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[node\n")
    code, out, err = bus_load_command(capsys, "--table", str(bad))
    assert (code, out) == (2, "")
    assert err.count("\n") == 1 and str(bad) in err


def test_the_lean_profile_fits_1_mbit_at_1_khz_within_70_percent_in_its_busiest_cycle(
    capsys: pytest.CaptureFixture[str],
) -> None:
    lean = load_table(DEFAULT_TABLE_PATH).with_pdo_profile("lean")
    load = bus_load(lockstep_traffic(lean, 1000.0), 1000.0, 1_000_000)
    # Every SYNC: RPDO1 and RPDO2 (135 bits each), SYNC (65), TPDO1 (85), a heartbeat (65); the
    # seven 8-byte TPDOs every 10th SYNC take turns (start values 1..7): one of them (135) at most.
    assert load.peak_cycle_worst_case == pytest.approx((2 * 135 + 65 + 85 + 65 + 135) / 1000)
    assert load.peak_cycle_worst_case <= 0.70
    code, out, err = bus_load_command(capsys, "--profile", "lean", "--rate-hz", "1000", "-b", "1M")
    assert (code, err) == (0, "")
    assert "PDO profile lean" in out.splitlines()[0]
    assert [line.split()[-2] for line in out.splitlines() if line.startswith("1 Mbit/s")] == ["62.0"]


def test_turns_by_sync_counter_that_meet_count_together() -> None:
    # Two TPDOs every 10th SYNC from counters 1 and 11: the same turn (11 - 1 is a multiple of 10).
    frames = [
        Traffic("TPDO2", cob_id(FunctionCode.TPDO2, 1), 8, 100.0, True, sync_phase=(10, 1)),
        Traffic("TPDO3", cob_id(FunctionCode.TPDO3, 1), 8, 100.0, True, sync_phase=(10, 11)),
        Traffic("TPDO4", cob_id(FunctionCode.TPDO4, 1), 8, 100.0, True, sync_phase=(10, 2)),
    ]
    assert bus_load(frames, 1000.0, 1_000_000).peak_cycle_worst_case == pytest.approx(2 * 135 / 1000)


def test_a_sixteen_module_robots_line_says_what_a_real_bus_would_carry_per_profile() -> None:
    # `hilrig sim --modules 16` prints this beside the run on the virtual bus (no bit rate): the
    # same arithmetic as `hilrig bus-load --modules 16 [--profile lean] -b 1M`.
    table = load_table(DEFAULT_TABLE_PATH)
    node_ids = list(range(1, 17))
    assert robot_load_line(table, node_ids, 1000.0, profile="full", master_heartbeat_ms=20) == (
        "profile full, 16 modules at 1000 Hz on 1 Mbit/s: 2109.5 % worst case, busiest cycle "
        "2413.0 % OVERLOAD; within 70.0 % up to 29 Hz"
    )
    assert robot_load_line(table, node_ids, 1000.0, profile="lean", master_heartbeat_ms=20) == (
        "profile lean, 16 modules at 1000 Hz on 1 Mbit/s: 727.1 % worst case, busiest cycle "
        "901.0 % OVERLOAD; within 70.0 % up to 77.6 Hz"
    )
    lean = table.with_pdo_profile("lean")
    traffic = lockstep_traffic(lean, 1000.0, node_ids=node_ids, master_heartbeat_ms=20)
    load = bus_load(traffic, 1000.0, 1_000_000)
    assert round(100 * load.worst_case, 1) == 727.1
    assert highest_rate_hz(lean, 1_000_000, node_ids=node_ids, master_heartbeat_ms=20) == 77.6
    assert robot_load_line(table, [1], 1000.0, profile="lean").startswith(
        "profile lean, 1 module at 1000 Hz on 1 Mbit/s: 51."
    )
