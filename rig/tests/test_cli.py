"""The `hilrig` command line without a real bus: argument handling and its messages, `fields`,
and every bus command against the in-process FakeJointNode on python-can's virtual bus."""

from __future__ import annotations

import itertools
import re
import subprocess
import sys
from pathlib import Path

import can
import pytest

from boardproto.cia301 import (
    NMT_COB_ID,
    SYNC_COB_ID,
    FunctionCode,
    NmtCommand,
    NmtState,
    cob_id,
    emcy_cob_id,
    heartbeat_cob_id,
    sdo_request_cob_id,
    sdo_response_cob_id,
)
from hilrig.apps.demo import ScenarioFileError, load_scenario
from hilrig.cli import COMMAND_MODULES, commands, main
from hilrig.session.buslog import whole_file_logger
from hilrig.session.fake_node import FakeJointNode
from hilrig.table import EmcyCode, LedPattern, RigTable

DEFAULT_KP = RigTable.load().field("velocity_kp").default  # from board.toml, not a copy
NODE_ID = RigTable.load().board.node.default_node_id  # the fake node's: board.toml's default

HILRIG = [sys.executable, "-m", "hilrig.cli"]
_channels = itertools.count()


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def on_bus(channel: str) -> list[str]:
    return ["--interface", "virtual", "--channel", channel, "--sdo-timeout", "2"]


# --- the command line ------------------------------------------------------------------
@pytest.mark.parametrize("command", [c.name for c in commands()])
def test_every_command_has_help(capsys: pytest.CaptureFixture[str], command: str) -> None:
    code, out, _ = run(capsys, command, "--help")
    assert code == 0
    assert out.startswith(f"usage: hilrig {command}")
    description = out.split("\noptions:")[0]
    assert re.search(rf"^  .*hilrig {command}\b", description, re.MULTILINE), "expected examples"


def test_top_level_help_lists_every_registered_command(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "--help")
    assert code == 0
    for name in ("fields", "get", "set", "watch", "scan", "record", "replay", "sim"):
        assert f"    {name} " in out
    assert len(COMMAND_MODULES) == len(set(COMMAND_MODULES))


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["set", "velocity_kp"], "expected NAME=VALUE, got 'velocity_kp' (e.g. velocity_kp=0.2)"),
        (["set", "velocity_kp=fast"], "velocity_kp: expected a number, got 'fast'"),
        (["set", "velocity_kp=nan"], "expected a finite number"),
        (["set", "motor_encoder_counts=1.5"], "expected a whole number"),
        (
            ["get", "velocity_kpp"],
            "no board field or HIL I/O object named 'velocity_kpp'; did you mean 'velocity_kp'",
        ),
        (["set", "velocty_kp=1"], "did you mean 'velocity_kp'"),
        (["watch", "motor_velocty"], "did you mean 'motor_velocity'"),
        (
            ["get", "velocity_kp", "--node-id", "200"],
            "expected a node id 1..127 (decimal or 0x hex, e.g. 0x10), got 200",
        ),
        (["get", "velocity_kp", "-n", "sixteen"], "expected a node id 1..127"),
        (
            ["get", "velocity_kp", "--interface", "socketcn"],
            "unknown python-can interface 'socketcn'; did you mean socketcan",
        ),
        (["scan", "--interface", "pcann"], "did you mean pcan"),
        (["scan", "--listen", "0"], "expected a finite number > 0"),
        (["record", "bus.txt"], "bus.txt does not end in .log, .asc, .blf, .mf4, .csv or .trc"),
        (["replay", "no-such.log", "--decode"], "log no-such.log does not exist; record one"),
        (["watch", "--once", "--count", "3"], "not allowed with argument"),
        (
            ["get", "velocity_kp", "--eds", "nowhere.eds"],
            "EDS nowhere.eds does not exist; run `make build`, or give --eds FILE",
        ),
        (["fields", "--kind", "sensors"], "invalid choice: 'sensors'"),
        (["fields", "no_such_thing"], "no field contains 'no_such_thing'"),
        (["sim", "--scenario", "nowhere.py"], "scenario nowhere.py does not exist"),
        (
            ["sim", "--fault", "freeze:thermistor@1"],
            "unknown sensor 'thermistor'; sensors: motor_encoder_counts",
        ),
        (["replay", "--trace", "x.txt", "x.log"], "x.txt does not end in .rrd"),
        (["sim", "--fault", "kill@1+1"], "kill happens once, at its start; drop the +DURATION"),
        (
            ["sim", "-b", "fast"],
            "argument -b/--bitrate: expected a bit rate in bit/s like 125000, 500k or 1M",
        ),
        (["sim", "--bitrate", "0"], "got '0'"),
        (["frobnicate"], "invalid choice: 'frobnicate'"),
        (["lss", "set", "5"], "the following arguments are required: --serial"),
        (["lss", "set", "5", "--serial", "twelve"], "expected a number (decimal or 0x hex), got 'twelve'"),
        (["lss", "set", "200", "--serial", "1"], "expected a node id 1..127"),
        (["lss", "number", "--first-id", "0"], "expected a node id 1..127"),
        (["params", "load", "nowhere.dcf"], "DCF nowhere.dcf does not exist; `hilrig params save FILE.dcf`"),
        (["params", "save"], "the following arguments are required: FILE.dcf"),
        ([], "the following arguments are required: COMMAND"),
    ],
)
def test_a_bad_command_line_is_one_line_and_exit_code_2(
    capsys: pytest.CaptureFixture[str], argv: list[str], expected: str
) -> None:
    code, out, err = run(capsys, *argv)
    assert code == 2
    assert out == ""
    assert expected in err
    assert err.count("\n") == 1, f"expected one line, got {err!r}"
    assert err.startswith("hilrig")


def test_fields_lists_index_unit_kind_access_range_default(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "fields")
    assert code == 0
    lines = out.splitlines()
    assert lines[0].split() == ["name", "index", "unit", "kind", "access", "range", "default"]
    table = RigTable.load()
    assert len(lines) == 1 + len(table.names)
    kp = table.field("velocity_kp")
    row = next(line.split() for line in lines if line.startswith("velocity_kp "))
    assert row == ["velocity_kp", f"0x{kp.index:04X}", kp.unit, "parameter", "rw", "0..10", f"{kp.default:g}"]
    duty = next(line.split() for line in lines if line.startswith("motor_duty "))
    assert duty[3:6] == ["hil_output", "ro", "-10000..10000"]


def test_fields_filters_by_kind_and_substring(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "fields", "velocity", "--kind", "virtual_sensor", "--kind", "command")
    assert code == 0
    names = [line.split()[0] for line in out.splitlines()[1:]]
    assert names == ["motor_velocity", "output_velocity", "velocity_setpoint", "target_velocity"]


def test_console_script_exit_codes_without_traceback(tmp_path: Path) -> None:
    usage = subprocess.run([*HILRIG, "set", "velocity_kp"], capture_output=True, text=True, check=False)
    assert usage.returncode == 2
    assert usage.stderr.strip() == (
        "hilrig set: error: expected NAME=VALUE, got 'velocity_kp' (e.g. velocity_kp=0.2)"
    )
    silent = subprocess.run(
        [*HILRIG, "get", "velocity_kp", "-i", "virtual", "-c", "nobody-here", "--sdo-timeout", "0.2"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert silent.returncode == 1
    assert silent.stdout == ""
    assert "Traceback" not in silent.stderr
    assert silent.stderr.count("\n") == 1, silent.stderr
    assert "read velocity_kp: node 0x10 did not answer" in silent.stderr
    assert "`hilrig scan` lists the nodes that answer" in silent.stderr
    fields = subprocess.run([*HILRIG, "fields", "winding"], capture_output=True, text=True, check=False)
    assert fields.returncode == 0
    assert "winding_temperature" in fields.stdout


def test_a_bus_that_does_not_open_is_one_line_exit_code_1(capsys: pytest.CaptureFixture[str]) -> None:
    # No such SocketCAN interface (or, natively, no SocketCAN at all): the command ran and failed.
    code, out, err = run(capsys, "get", "velocity_kp", "-i", "socketcan", "-c", "hilrig-nosuch0")
    assert code == 1
    assert out == ""
    assert err.startswith("hilrig get: error: cannot open socketcan channel hilrig-nosuch0: ")
    assert err.count("\n") == 1


# --- against the fake node on the virtual bus -------------------------------------------
def test_get_prints_values_with_units(
    capsys: pytest.CaptureFixture[str], fake: FakeJointNode, channel: str
) -> None:
    code, out, err = run(capsys, "get", "velocity_kp", "winding_temperature", *on_bus(channel))
    assert (code, err) == (0, "")
    assert [line.split() for line in out.splitlines()] == [
        ["velocity_kp", "=", f"{DEFAULT_KP:g}", "1/(rad/s)"],
        ["winding_temperature", "=", "25", "degC"],
    ]


def test_set_writes_reads_back_and_explains_a_refusal(
    capsys: pytest.CaptureFixture[str], fake: FakeJointNode, channel: str
) -> None:
    code, out, err = run(
        capsys, "set", "velocity_kp=0.25", "velocity_ki=1000", "torque_kp=1", *on_bus(channel)
    )
    assert code == 1
    assert out.split() == ["velocity_kp", "=", "0.25", "1/(rad/s)"]
    assert err == (
        "hilrig set: error: node 0x10 refused write velocity_ki: 0x06090031 value too high "
        "(max 100.0); not attempted: torque_kp\n"
    )
    code, out, _ = run(capsys, "get", "velocity_kp", "torque_kp", *on_bus(channel))
    assert code == 0
    assert [line.split()[2] for line in out.splitlines()] == [
        "0.25",
        f"{RigTable.load().field('torque_kp').default:g}",
    ]


def test_get_of_a_read_only_write_is_refused_in_words(
    capsys: pytest.CaptureFixture[str], fake: FakeJointNode, channel: str
) -> None:
    code, _, err = run(capsys, "set", "velocity_kp=-1", *on_bus(channel))
    assert code == 1
    assert "0x06090032 value too low (min 0.0)" in err


def test_scan_finds_the_node_with_its_identity(
    capsys: pytest.CaptureFixture[str], fake: FakeJointNode, channel: str
) -> None:
    code, out, err = run(capsys, "scan", "-i", "virtual", "-c", channel, "--listen", "0.5")
    assert code == 0, err
    header, row = out.splitlines()
    assert header.split() == ["node", "state", "device", "name", "vendor", "product", "revision"]
    node = RigTable.load().board.node
    assert row.split() == [
        "0x10",
        "pre_operational",
        node.device_name,
        f"0x{node.vendor_id:08X}",
        f"0x{node.product_code:08X}",
        f"0x{node.revision:08X}",
    ]
    assert "1 node on virtual channel" in err


def test_scan_of_an_empty_bus_says_so(capsys: pytest.CaptureFixture[str], channel: str) -> None:
    code, out, err = run(capsys, "scan", "-i", "virtual", "-c", channel, "--listen", "0.2")
    assert (code, out) == (1, "")
    assert "no CANopen node answered on virtual channel" in err.splitlines()[-1]


def test_watch_once_starts_the_node_produces_sync_and_shows_values(
    capsys: pytest.CaptureFixture[str], fake: FakeJointNode, channel: str
) -> None:
    code, out, err = run(
        capsys,
        "watch",
        "--once",
        "--nmt-start",
        "--sync-period-ms",
        "5",
        "motor_duty",
        "motor_velocity",
        "velocity_kp",
        *on_bus(channel),
    )
    assert (code, err) == (0, "")
    title, header, *rows = out.splitlines()
    assert title.startswith("node 0x10 ") and f"on virtual {channel}, SYNC every 5 ms" in title
    assert header.split() == ["name", "value", "unit", "via", "updates"]
    assert [row.split()[:3] for row in rows] == [
        ["motor_duty", "0", "0.01%"],
        ["motor_velocity", "0", "rad/s"],
        ["velocity_kp", f"{DEFAULT_KP:g}", "1/(rad/s)"],
    ]
    assert "TPDO1 (0x190)" in rows[0] and rows[2].split()[3] == "SDO"
    assert "\x1b[" not in out, "no ANSI codes when not on a terminal"
    assert fake.syncs, "expected SYNCs from --sync-period-ms"


def test_watch_takes_the_tpdo_mapping_from_the_eds(
    capsys: pytest.CaptureFixture[str], fake: FakeJointNode, channel: str
) -> None:
    # The EDS's PDO COB-IDs are $NODEID+...: resolved for the node watched, as when read from it.
    argv = ["--once", "--nmt-start", "--sync-period-ms", "5", "--pdo-from-eds", "motor_duty"]
    code, out, err = run(capsys, "watch", *argv, *on_bus(channel))
    assert (code, err) == (0, "")
    assert f"TPDO1 (0x{cob_id(FunctionCode.TPDO1, NODE_ID):03X})" in out.splitlines()[2]


def test_watch_once_without_sync_says_what_is_missing(
    capsys: pytest.CaptureFixture[str], fake: FakeJointNode, channel: str
) -> None:
    code, _, err = run(capsys, "watch", "--once", "--timeout", "0.3", "motor_duty", *on_bus(channel))
    assert code == 1
    assert err.strip().endswith(
        "no TPDO with motor_duty within 0.3 s; is the node operational "
        "(--nmt-start) and is anything sending SYNC (--sync-period-ms 10)?"
    )


def test_record_then_replay_decode(
    capsys: pytest.CaptureFixture[str], fake: FakeJointNode, channel: str, tmp_path: Path
) -> None:
    log = tmp_path / "bus.log"
    frames = 120  # a busy host lets record's SYNCs run ahead of the fake's answers: room for some
    code, _, err = run(
        capsys,
        "record",
        str(log),
        "--nmt-start",
        "--sync-period-ms",
        "5",
        "--count",
        str(frames),
        "-i",
        "virtual",
        "-c",
        channel,
    )
    assert code == 0, err
    assert f"record: {frames} frames written to {log}" in err
    assert not list(tmp_path.glob(".*partial*")), "the partial file is renamed, not left behind"
    assert sum(1 for _ in can.LogReader(str(log))) == frames
    code, out, err = run(capsys, "replay", str(log), "--decode")
    assert (code, err) == (0, "")
    lines = out.splitlines()
    assert len(lines) == frames
    assert any("0x000  NMT command 0x01 to node 0x10" in line for line in lines)
    assert any("0x080  SYNC 1" in line for line in lines)
    tpdo1 = f"0x190  TPDO1  motor_duty=0 0.01%  led_pattern=on ({int(LedPattern.ON)})"
    assert any(tpdo1 in line for line in lines)
    code, out, _ = run(capsys, "replay", str(log), "--decode", "--field", "motor_velocity")
    assert code == 0
    assert out and all(
        "TPDO2  motor_velocity=0 rad/s" in line and "output_velocity" not in line for line in out.splitlines()
    )


def test_record_then_replay_into_a_trace(
    capsys: pytest.CaptureFixture[str], fake: FakeJointNode, channel: str, tmp_path: Path
) -> None:
    from hilrig.observe.paths import entity_paths
    from hilrig.observe.reader import Trace

    log, rrd = tmp_path / "bench.log", tmp_path / "bench.rrd"
    # The SYNCs come from record's wall-clock producer and the fake answers on its own thread: on
    # a busy host (the bus stage's VM beside this stage) most of 60 frames were SYNCs, two with a
    # TPDO1. What is checked holds for any interleaving: the trace has motor_duty at exactly the
    # cycles the log has a TPDO1 in. Enough frames that some TPDO1 is among them.
    argv = ["--nmt-start", "--sync-period-ms", "5", "--count", "200", "-i", "virtual", "-c", channel]
    code, _, err = run(capsys, "record", str(log), *argv)
    assert code == 0, err
    code, out, err = run(capsys, "replay", str(log), "--trace", str(rrd))
    assert code == 0, err
    assert out == f"hilrig view {rrd}   # add --web on a machine without a display\n"
    assert not list(tmp_path.glob(".*partial*"))
    # Which cycles (SYNC index) the log has a TPDO1 for: exactly those carry motor_duty.
    tpdo1 = RigTable.load().board.tpdo(1).cob_id(NODE_ID)
    expected: list[int] = []
    syncs = -1
    for message in can.LogReader(str(log)):
        if message.arbitration_id == SYNC_COB_ID:
            syncs += 1
        elif message.arbitration_id == tpdo1 and syncs >= 0 and expected[-1:] != [syncs]:
            expected.append(syncs)
    assert expected, "no TPDO1 in the log: nothing to compare"
    paths = entity_paths(RigTable.load())
    trace = Trace.read(rrd)
    assert trace.cycles[paths["motor_duty"]] == expected
    assert trace.scalars[paths["led_pattern"]] == [float(LedPattern.ON)] * len(expected)  # the fake's law
    heartbeats = {
        bytes(m.data) for m in can.LogReader(str(log)) if m.arbitration_id == heartbeat_cob_id(NODE_ID)
    }
    nmt = [text for text, _ in trace.texts["/events/nmt"]]
    assert len(nmt) == len(heartbeats), (nmt, heartbeats)  # one entry per state change seen
    assert f"{syncs + 1} cycles" in err


def test_record_works_out_the_nmt_target_before_it_counts_frames(
    capsys: pytest.CaptureFixture[str],
    fake: FakeJointNode,
    channel: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # Loading the table took seconds in the VM: the node's heartbeats meanwhile filled --count
    # before the NMT command went out (a scenario's recording of 60 heartbeats, no NMT).
    from hilrig.cli import record

    # The order is the point (table, then bus); the node's own heartbeats would race the NMT
    # command for the log's first place on a busy host.
    fake.local.nmt.stop_heartbeat()
    order: list[str] = []
    real_load_table, real_open_bus = record.load_table, record.open_bus

    def load_table(args: object) -> RigTable:
        order.append("table")
        return real_load_table(args)

    def open_bus(*args: object, **kwargs: object) -> can.BusABC:
        order.append("bus")
        return real_open_bus(*args, **kwargs)

    monkeypatch.setattr(record, "load_table", load_table)
    monkeypatch.setattr(record, "open_bus", open_bus)
    log = tmp_path / "bench.log"
    argv = ["--nmt-start", "--count", "1", "-i", "virtual", "-c", channel]
    code, _, err = run(capsys, "record", str(log), *argv)
    assert code == 0, err
    assert order == ["table", "bus"]
    first = next(iter(can.LogReader(str(log))))
    assert (first.arbitration_id, bytes(first.data)) == (NMT_COB_ID, bytes([NmtCommand.START, NODE_ID]))


def test_replay_sends_the_log_into_the_bus(
    capsys: pytest.CaptureFixture[str], channel: str, tmp_path: Path
) -> None:
    log = tmp_path / "in.log"
    with whole_file_logger(log) as logger:
        for n in range(5):
            logger(
                can.Message(
                    timestamp=1.0 + n * 1e-3, arbitration_id=SYNC_COB_ID, data=[n + 1], is_extended_id=False
                )
            )
    with can.Bus(interface="virtual", channel=channel) as listener:
        code, _, err = run(capsys, "replay", str(log), "-i", "virtual", "-c", channel)
        assert code == 0
        assert "replay: 5 frames sent" in err
        received = [listener.recv(1.0) for _ in range(5)]
    assert [bytes(m.data) for m in received if m is not None] == [bytes([n + 1]) for n in range(5)]


def test_replay_as_master_leaves_out_what_the_node_sent(
    capsys: pytest.CaptureFixture[str], channel: str, tmp_path: Path
) -> None:
    log = tmp_path / "run.log"
    rpdo1, sdo_request = cob_id(FunctionCode.RPDO1, NODE_ID), sdo_request_cob_id(NODE_ID)
    flood, other_tpdo1 = 0x001, cob_id(FunctionCode.TPDO1, NODE_ID + 1)
    frames = [
        (NMT_COB_ID, bytes([NmtCommand.START, NODE_ID])),  # NMT start node 0x10: the master's
        (heartbeat_cob_id(NODE_ID), bytes([NmtState.OPERATIONAL])),  # heartbeat of node 0x10: the node's own
        (rpdo1, bytes(8)),  # RPDO1 to node 0x10: the master's
        (SYNC_COB_ID, b"\x01"),  # SYNC: the master's
        (cob_id(FunctionCode.TPDO1, NODE_ID), bytes(4)),  # TPDO1 of node 0x10: the node's own
        (sdo_response_cob_id(NODE_ID), bytes(8)),  # SDO answer of node 0x10: the node's own
        (emcy_cob_id(NODE_ID), bytes(8)),  # EMCY of node 0x10: the node's own
        (sdo_request, bytes(8)),  # SDO request to node 0x10: the master's
        (flood, bytes(8)),  # an injected flood frame: not the node's
        (other_tpdo1, bytes(4)),  # TPDO1 of another node (0x11): not node 0x10's
    ]
    with whole_file_logger(log) as logger:
        for n, (can_id, data) in enumerate(frames):
            logger(
                can.Message(timestamp=1.0 + n * 1e-3, arbitration_id=can_id, data=data, is_extended_id=False)
            )
    with can.Bus(interface="virtual", channel=channel) as listener:
        code, _, err = run(
            capsys, "replay", str(log), "--as-master", "--no-timing", "-i", "virtual", "-c", channel
        )
        assert code == 0, err
        assert "without node 0x10's own frames" in err and "replay: 6 frames sent" in err
        received = [listener.recv(1.0) for _ in range(6)]
    assert [m.arbitration_id for m in received if m is not None] == [
        NMT_COB_ID,
        rpdo1,
        SYNC_COB_ID,
        sdo_request,
        flood,
        other_tpdo1,
    ]


def test_an_interrupted_recording_is_still_a_whole_file(tmp_path: Path) -> None:
    log = tmp_path / "cut.blf"
    with pytest.raises(KeyboardInterrupt), whole_file_logger(log) as logger:
        for n in range(3):
            logger(can.Message(timestamp=float(n), arbitration_id=0x123, data=[n], is_extended_id=False))
        raise KeyboardInterrupt
    assert [m.data[0] for m in can.LogReader(str(log))] == [0, 1, 2]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cut.blf"]


def test_a_scenario_file_must_define_scenario(tmp_path: Path) -> None:
    script = tmp_path / "empty.py"
    script.write_text("def run(rig):\n    pass\n")
    with pytest.raises(ScenarioFileError, match="defines no function `scenario"):
        load_scenario(script)
    script.write_text("def scenario(rig):\n    rig.run(seconds=0.1)\n")
    assert load_scenario(script).__name__ == "scenario"


def test_bus_load_is_a_command_warns_above_70_and_fails_above_100_percent(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code, out, err = run(capsys, "bus-load", "--rate-hz", "100", "--bitrate", "125k", "--bitrate", "1M")
    assert code == 1
    rows = {row.split()[0] for row in out.splitlines() if row[:1].isdigit() and "bit/s" in row}
    assert rows == {"125", "1"}
    # 125 kbit/s at 100 Hz is about 91 % nominal and 111 % worst case: it does not fit; 1 Mbit/s
    # is about 14 %: fine.
    verdicts = [line.split(":")[:2] for line in out.splitlines() if line.startswith(("OVERLOAD", "WARNING"))]
    assert verdicts == [["OVERLOAD", " 125 kbit/s"]], out
    # The busiest cycle of the default mapping: 3 RPDOs + 7 TPDOs of 8 bytes (135 bits each worst
    # case), TPDO1 of 3 bytes (85), SYNC and heartbeat (65 each) = 1565 bits; within 70 %:
    # 0.7 * 125_000 / 1565 = 55.9 Hz, 0.7 * 1_000_000 / 1565 = 447.28 Hz (both rounded down to 0.1 Hz)
    assert (
        out.splitlines()[-1]
        == "highest SYNC rate within 70 % (worst case): 125 kbit/s: 55.9 Hz, 1 Mbit/s: 447.2 Hz"
    )
    assert (
        err
        == "hilrig bus-load: error: at 100 Hz the exchange does not fit 125 kbit/s (above 100 % of the bus)\n"
    )
    # A robot of 8 such modules (node ids 1..8), one shared SYNC and the master heartbeat:
    # 8 * (1565 - 65) + 65 + 65 = 12_130 bits in the busiest cycle; at 25 Hz 303_250 bit/s, 60.65 %
    # of 500 kbit/s; within 70 %: 0.7 * 500_000 / 12_130 = 28.85 Hz, 0.7 * 1_000_000 / 12_130 =
    # 57.71 Hz (figures for the README: the default mapping on a robot)
    code, out, err = run(capsys, "bus-load", "--modules", "8", "--rate-hz", "25", "-b", "500k", "-b", "1M")
    assert (code, err) == (0, "")
    assert "RPDO1 x8          0x201..0x208" in out and "60.6 %" in out  # 60.65 printed to 0.1
    assert out.splitlines()[-1].endswith(": 500 kbit/s: 28.8 Hz, 1 Mbit/s: 57.7 Hz")
    code, out, err = run(capsys, "bus-load", "--rate-hz", "100", "--bitrate", "200k")
    assert (code, err) == (0, "")
    assert "WARNING: 200 kbit/s" in out  # about 69 % worst case, 78 % in the busiest cycle


def test_watch_shows_the_latest_emcys_under_the_table() -> None:
    import io

    from canopen.emcy import EmcyError

    from hilrig.cli.watch import EMCY_LINES, Board, Screen

    board = Board([RigTable.load().entry("motor_duty")])
    about_rpdo1 = bytes([0x00, 0x14, 0, 0, 0])  # the board's manufacturer bytes: the object, LE
    for n in range(EMCY_LINES + 1):
        board.on_emcy(EmcyError(EmcyCode.PDO_LENGTH_ERROR, 0x11, about_rpdo1, board.started + n))
    out = io.StringIO()
    Screen(out, in_place=False).draw("title", board.rows(), board.emcy_lines())
    lines = out.getvalue().splitlines()
    assert lines[2].split()[0] == "motor_duty"
    assert lines[3:] == [
        "EMCY 0x8210 pdo_length_error (Monitoring) register 0x11 about 0x1400, bytes 00 14 00 00 00"
        f" at {n}.0 s"
        for n in range(1, EMCY_LINES + 1)
    ], "the latest EMCY_LINES, oldest first"


def test_replay_decode_names_an_emcy_by_cia_301_and_by_the_board(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    log = tmp_path / "emcy.log"
    node = RigTable.load().board.node.default_node_id
    emcy = bytes([0x30, 0x81, 0x11, 0x16, 0x10, 0x7F, 0, 0])  # heartbeat of node 0x7F lost
    with can.Logger(str(log)) as logger:
        frame = can.Message(arbitration_id=emcy_cob_id(node), data=emcy, is_extended_id=False)
        logger.on_message_received(frame)
    code, out, err = run(capsys, "replay", str(log), "--decode")
    assert (code, err) == (0, "")
    assert out.strip() == (
        f"0.000000  0x{emcy_cob_id(node):03X}  EMCY 0x8130 heartbeat_error (Monitoring) register 0x11 "
        f"about 0x1016, bytes 16 10 7f 00 00 from node 0x{node:02X}"
    )


def test_pdo_apply_writes_a_profile_and_stores_it(
    capsys: pytest.CaptureFixture[str], fake: FakeJointNode, channel: str
) -> None:
    lean = RigTable.load().board.pdo_profile("lean")
    code, out, err = run(capsys, "pdo", "apply", "lean", *on_bus(channel))
    assert code == 0, err
    tpdo2 = next(p for p in lean.tpdos if p.number == 2)
    tpdo2_id = tpdo2.cob_id(RigTable.load().board.node.default_node_id)
    assert (
        f"TPDO2 (0x{tpdo2_id:03X}): every 10th SYNC from SYNC counter 1: motor_velocity, output_velocity"
        in out.splitlines()
    )
    assert not any(line.startswith("RPDO3") for line in out.splitlines()), "RPDO3 is off in lean"
    assert "profile lean stored (0x1010:02)" in err
    assert fake.local.sdo[tpdo2.communication_index][6].raw == tpdo2.sync_start == 1
    assert fake.local.sdo[0x1019].raw == lean.sync_counter_overflow
