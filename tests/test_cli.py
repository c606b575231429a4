"""The `hilrig` console script against the real firmware on a private bus: each command run as
a subprocess inside the bus's namespace, as a person at a bench would run it. Python starts
slowly in the micro-VM, so each call checks as much as it can."""

from __future__ import annotations

import subprocess
import zlib
from pathlib import Path

import can
import cantools
import pytest
from conftest import NODE_ID, REPO, NodeUnderTest, own_master, run_hilrig

from boardproto import load_table
from boardproto.cia301 import SYNC_COB_ID
from boardproto.cia302 import ImageHeader
from hilrig.cli import forked
from hilrig.session.netns import PrivateBus

pytestmark = pytest.mark.bus

HILRIG = str(REPO / ".venv" / "bin" / "hilrig")
TABLE = load_table(REPO / "protocol" / "board.toml")
RPDO1 = TABLE.rpdo(1).cob_id(NODE_ID)
# Hang guards for the software-emulated VM, not timing checks.
CALL_TIMEOUT_S = 300
SDO_TIMEOUT = ["--sdo-timeout", "5"]


hilrig = run_hilrig


@pytest.mark.requirement("SDO_01", "SDO_03")
def test_scan_get_and_set_against_the_firmware(
    private_bus: PrivateBus, node_under_test: NodeUnderTest
) -> None:
    scan = hilrig(private_bus, "scan", "--listen", "3", "--sdo-timeout", "5")
    assert scan.returncode == 0, scan.stderr
    node = TABLE.node
    rows = [line.split() for line in scan.stdout.splitlines()[1:]]
    assert rows == [
        [
            f"0x{NODE_ID:02X}",
            "pre_operational",
            node.device_name,
            f"0x{node.vendor_id:08X}",
            f"0x{node.product_code:08X}",
            f"0x{node.revision:08X}",
        ]
    ]

    kp, ki = TABLE.field("velocity_kp"), TABLE.field("velocity_ki")
    with own_master(private_bus) as master:
        master.sdo[kp.index].raw = 0.125  # the master sets, `get` reads
    got = hilrig(private_bus, "get", "velocity_kp", "winding_temperature", *SDO_TIMEOUT)
    assert got.returncode == 0, got.stderr
    assert [line.split()[:3] for line in got.stdout.splitlines()] == [
        ["velocity_kp", "=", "0.125"],
        ["winding_temperature", "=", "25"],
    ]
    assert got.stdout.splitlines()[1].split()[3] == "degC"

    # `set` writes, the master reads; the second value is refused and explained in words.
    done = hilrig(
        private_bus, "set", "velocity_ki=2.5", f"velocity_kp={kp.max * 2:g}", "torque_kp=0.5", *SDO_TIMEOUT
    )
    assert done.returncode == 1
    assert done.stdout.split()[:3] == ["velocity_ki", "=", "2.5"]
    with own_master(private_bus) as master:
        assert master.sdo[ki.index].raw == pytest.approx(2.5)
        assert master.sdo[kp.index].raw == pytest.approx(0.125), "a refused write changes nothing"
    assert done.stderr == (
        f"hilrig set: error: node 0x{NODE_ID:02X} refused write velocity_kp: "
        f"0x06090031 value too high (max {kp.max}); not attempted: torque_kp\n"
    )


@pytest.mark.requirement("SDO_01", "NMT_01")
def test_sdo_by_index_and_nmt_against_the_firmware(
    private_bus: PrivateBus, node_under_test: NodeUnderTest
) -> None:
    node = TABLE.node
    read = hilrig(private_bus, "sdo", "read", "0x1018:1", *SDO_TIMEOUT)
    assert read.returncode == 0, read.stderr
    assert read.stdout == (
        f"0x1018:01 Identity object.Vendor-ID = {node.vendor_id} (0x{node.vendor_id:08X}, u32)\n"
    )
    # u16 from the EDS; the master reads back what the command wrote
    written = hilrig(private_bus, "sdo", "write", "0x1017", "50", *SDO_TIMEOUT)
    assert written.returncode == 0, written.stderr
    assert written.stdout == "0x1017:00 Producer heartbeat time := 50 (0x0032, u16)\n"
    with own_master(private_bus) as master:
        assert master.sdo[0x1017].raw == 50
    # NMT start, and the heartbeat that then says operational (30 s: a hang guard in the VM)
    started = hilrig(private_bus, "nmt", "start", "--wait", "--timeout", "30")
    assert started.returncode == 0, started.stderr
    assert started.stdout.startswith(f"node 0x{NODE_ID:02X}: operational, "), started.stdout


@pytest.mark.requirement("REC_01", "SDO_05")
def test_capture_records_on_the_board_and_uploads_by_block_transfer(
    private_bus: PrivateBus, node_under_test: NodeUnderTest, scenario_dir: Path
) -> None:
    """`hilrig capture` as master of the lockstep firmware (NMT start, SYNC): the recorder
    samples two fields for 200 cycles, the recording comes back by block upload as a CSV."""
    csv_path = scenario_dir / "capture.csv"
    master = ["--nmt-start", "--sync-period-ms", "5", "--timeout", "120", *SDO_TIMEOUT]
    fields = ["motor_velocity", "fault_flags"]
    captured = hilrig(private_bus, "capture", *fields, "--samples", "200", "-o", str(csv_path), *master)
    assert captured.returncode == 0, captured.stderr
    rows = csv_path.read_text().splitlines()
    assert rows[0].startswith("cycle,time [s],motor_velocity [rad/s],fault_flags"), rows[0]
    assert len(rows) == 1 + 200
    cycles = [int(row.split(",")[0]) for row in rows[1:]]
    assert cycles == list(range(cycles[0], cycles[0] + 200)), "one sample every cycle, none skipped"


@pytest.mark.requirement("RIG_03")
def test_watch_record_and_replay_decode(
    private_bus: PrivateBus, node_under_test: NodeUnderTest, scenario_dir: Path
) -> None:
    log = scenario_dir / "cli-record.log"
    # No master in this test: the CLI starts the node and produces SYNC itself (bring-up mode).
    recorded = hilrig(
        private_bus, "record", str(log), "--nmt-start", "--sync-period-ms", "10", "--count", "60"
    )
    assert recorded.returncode == 0, recorded.stderr
    assert f"record: 60 frames written to {log}" in recorded.stderr
    assert not list(scenario_dir.glob(".cli-record.partial*"))

    watched = hilrig(
        private_bus,
        "watch",
        "--once",
        "--sync-period-ms",
        "10",
        "--timeout",
        "60",
        "motor_duty",
        "led_pattern",
        "winding_temperature",
        "velocity_ki",
        *SDO_TIMEOUT,
    )
    assert watched.returncode == 0, watched.stderr
    title, _header, *lines = watched.stdout.splitlines()
    assert title.startswith(f"node 0x{NODE_ID:02X} ")
    # Under the table, the EMCYs the node sent meanwhile (its sensors go stale without a rig).
    rows = [line for line in lines if not line.startswith("EMCY ")]
    by_name = {row.split()[0]: row.split() for row in rows}
    assert set(by_name) == {"motor_duty", "led_pattern", "winding_temperature", "velocity_ki"}
    assert by_name["motor_duty"][3:5] == ["TPDO1", f"(0x{TABLE.tpdo(1).cob_id(NODE_ID):03X})"]
    assert by_name["velocity_ki"][1:4] == [f"{TABLE.field('velocity_ki').default:g}", "1/rad", "SDO"]
    assert by_name["winding_temperature"][2:4] == ["degC", "TPDO8"]
    float(by_name["winding_temperature"][1])  # a number, not "-"

    # An EMCY while `watch` runs shows under its table: RPDO1 one byte short (the node is still
    # operational from `record --nmt-start`) is refused with EMCY pdo_length_error.
    # 120 tables of 0.5 s: the hang guard, should the EMCY never come.
    watch = [HILRIG, "watch", "--count", "120", "--interval", "0.5", "motor_duty", *SDO_TIMEOUT]
    live = subprocess.Popen(
        private_bus.command(watch),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert live.stdout is not None
        shown: list[str] = []
        for line in live.stdout:  # the first table: it listens; each later one ends in the EMCYs
            shown.append(line.rstrip("\n"))
            if line.startswith("node ") and len(shown) == 1:
                short = can.Message(arbitration_id=RPDO1, data=b"\x00", is_extended_id=False)
                node_under_test.bus.send(short)
            if line.startswith("EMCY 0x8210"):  # the stale sensors' EMCYs may come first
                break
    finally:
        live.kill()
        live.wait(timeout=CALL_TIMEOUT_S)
    assert shown[-1].startswith("EMCY 0x8210 pdo_length_error (Monitoring) register 0x11 about 0x1400"), (
        "\n".join(shown) + live.stderr.read() if live.stderr else ""
    )

    decoded = forked.run(["replay", str(log), "--decode"], timeout_s=CALL_TIMEOUT_S)
    assert decoded.returncode == 0, decoded.stderr
    lines = decoded.stdout.splitlines()
    assert len(lines) == 60
    assert any(f"NMT command 0x01 to node 0x{NODE_ID:02X}" in line for line in lines)
    assert any("0x080  SYNC 1" in line for line in lines)
    assert any("TPDO1  motor_duty=" in line and "led_pattern=" in line for line in lines)
    assert any("TPDO2  motor_velocity=" in line and "rad/s" in line for line in lines)


OTHER_PRODUCT = 0x4F544852


@pytest.mark.requirement("ID_01")
def test_every_writing_command_refuses_a_node_that_is_not_the_tables(
    private_bus: PrivateBus, node_under_test: NodeUnderTest, scenario_dir: Path
) -> None:
    """The joint's table with another product code (the same names and indices: only the
    identity tells the boards apart): each writing command reads the node's 0x1018 first and
    refuses, exit code 2, nothing written; with --force it writes."""
    node = TABLE.node
    line = f"product_code = 0x{node.product_code:08X}"
    other = scenario_dir / "other-board.toml"
    other.write_text(
        (REPO / "protocol" / "board.toml").read_text().replace(line, f"product_code = 0x{OTHER_PRODUCT:08X}")
    )
    dcf = scenario_dir / "saved.dcf"
    saved = hilrig(private_bus, "params", "save", str(dcf), *SDO_TIMEOUT)  # a read: no check
    assert saved.returncode == 0, saved.stderr
    image = scenario_dir / "other.img"
    payload = bytes(range(256)) * 4
    header = ImageHeader(
        product_code=OTHER_PRODUCT,
        software_version="9.9.9",
        payload_length=len(payload),
        payload_crc32=zlib.crc32(payload),
    )
    image.write_bytes(header.pack() + payload)  # the other table's image: only the node refuses it

    kp = TABLE.field("velocity_kp")
    # a field, the heartbeat time, the SYNC counter's period, TPDO2's transmission type (lean: 10)
    watched = [(kp.index, 0), (0x1017, 0), (0x1019, 0), (0x1801, 2)]
    with own_master(private_bus) as master:
        master.sdo[kp.index].raw = 0.125
        before = [master.sdo.upload(*address) for address in watched]
    writes = [
        ["set", "velocity_kp=0.25"],
        ["sdo", "write", "0x1017", "77"],
        ["pdo", "apply", "lean"],
        ["params", "load", str(dcf)],
        ["flash", str(image)],
        ["capture", "motor_velocity", "-o", str(scenario_dir / "capture.csv")],
    ]
    identity = f"vendor 0x{node.vendor_id:08X} product 0x{node.product_code:08X}"
    for command in writes:
        refused = hilrig(private_bus, *command, "--table", str(other), *SDO_TIMEOUT)
        assert refused.returncode == 2, (command, refused.stderr)
        assert refused.stdout == "", command
        error = refused.stderr.splitlines()[-1]
        assert f"error: node 0x{NODE_ID:02X} is {identity}, not the table's " in error, error
        assert f"product 0x{OTHER_PRODUCT:08X}" in error and "nothing written" in error, error
    assert not (scenario_dir / "capture.csv").exists()
    with own_master(private_bus) as master:
        assert [master.sdo.upload(*address) for address in watched] == before, "nothing written"

    forced = hilrig(private_bus, "set", "velocity_kp=0.25", "--table", str(other), "--force", *SDO_TIMEOUT)
    assert forced.returncode == 0, forced.stderr
    assert "writing anyway (--force)" in forced.stderr
    with own_master(private_bus) as master:
        assert master.sdo[kp.index].raw == pytest.approx(0.25)


SHORT_SCENARIO = """
from hilrig.table import ControlMode


def scenario(rig):
    rig.set("control_mode", ControlMode.VELOCITY)
    rig.set("velocity_setpoint", 2.0)
    rig.run(seconds=0.3)
"""


@pytest.mark.requirement("RIG_04")
def test_sim_injects_faults_from_the_command_line(scenario_dir: Path) -> None:
    scenario = scenario_dir / "short.py"
    scenario.write_text(SHORT_SCENARIO)
    out = scenario_dir / "sim"
    faults = ["freeze:thermistor_adc@0.02+0.05", "malformed:length@0.1", "restart@0.15"]
    # On a timed bus (-b) with room for the demo's full mapping: the same run, and its summary
    # says what the bus carried.
    timed = ["-b", "2M"]
    done = subprocess.run(
        [
            HILRIG,
            "sim",
            *timed,
            "--scenario",
            str(scenario),
            "--out",
            str(out),
            *(f"--fault={f}" for f in faults),
        ],
        capture_output=True,
        text=True,
        timeout=CALL_TIMEOUT_S,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    events = [line for line in done.stderr.splitlines() if " fault " in line]
    assert events == [
        "sim: t = 0.020 s  fault freeze:thermistor_adc@0.02+0.05: thermistor_adc frozen at its present value",
        "sim: t = 0.070 s  fault freeze:thermistor_adc@0.02+0.05: ended",
        "sim: t = 0.100 s  fault malformed:length@0.1: RPDO1 (0x210) sent with 7 bytes, not 8",
        "sim: t = 0.150 s  fault restart@0.15: firmware killed with SIGKILL, restarting",
        "sim: t = 0.150 s  fault restart@0.15: firmware booted again and is operational",
    ]
    summary = (out / "summary.txt").read_text()
    injected = [line.split(None, 2)[2] for line in summary.splitlines() if line.startswith("fault injected")]
    assert injected == [
        "t = 0.020 s  freeze:thermistor_adc@0.02+0.05: thermistor_adc frozen at its present value"
    ]
    assert "t = 0.150 s  restart@0.15: firmware booted again and is operational" in summary
    assert "300 cycles = 0.300 s" in summary
    timed_row = next(line for line in summary.splitlines() if line.startswith("timed bus"))
    assert "2 Mbit/s: load" in timed_row and "no frame late" in timed_row, timed_row
    firmware_log = (out / "firmware.log").read_text()
    assert "killed with SIGKILL and started again" in firmware_log
    assert (out / "trace.rrd").stat().st_size > 0

    # The bus log is candump text: cantools reads it with the build's DBC and names the values
    # (what `python -m cantools decode board.dbc < bus.log` prints; protocol/tests runs that
    # command itself, natively: a second Python start is dear in the micro-VM).
    database = cantools.database.load_file(str(REPO / "build/protocol/board.dbc"))
    named: dict[str, set[str]] = {"control_mode": set(), "fault_flags": set(), "led_pattern": set()}
    messages = {m.frame_id: m for m in database.messages}
    for entry in cantools.logreader.Parser((out / "bus.log").open()):
        message = messages.get(entry.frame_id)
        # The injected 7-byte RPDO1 does not decode: cantools says so, and so does the node.
        if message is not None and len(entry.data) == message.length:
            for name, value in message.decode(entry.data).items():
                if name in named:
                    named[name].add(str(value))
    assert "velocity" in named["control_mode"], named
    assert "none" in named["fault_flags"], named
    patterns = {v.name for v in TABLE.enum("led_pattern").values}
    assert named["led_pattern"] and named["led_pattern"] <= patterns, named


@pytest.mark.requirement("RIG_04")
def test_sim_reports_a_killed_firmware_with_the_evidence(scenario_dir: Path) -> None:
    scenario = scenario_dir / "short.py"
    scenario.write_text(SHORT_SCENARIO)
    out = scenario_dir / "sim"
    done = subprocess.run(
        [HILRIG, "sim", "--scenario", str(scenario), "--out", str(out), "--fault", "kill@0.1"],
        capture_output=True,
        text=True,
        timeout=CALL_TIMEOUT_S,
        check=False,
    )
    assert done.returncode == 1, done.stderr
    error = done.stderr.splitlines()[-1]
    assert error.startswith("hilrig sim: error: cycle 100 (t = 0.1 s): joint-firmware"), error
    assert "killed by SIGKILL" in error
    for name in ("trace.rrd", "bus.log", "firmware.log"):
        assert f"{out / name}" in error
        assert (out / name).stat().st_size > 0
    syncs = [m for m in can.LogReader(str(out / "bus.log")) if m.arbitration_id == SYNC_COB_ID]
    assert len(syncs) == 101, "cycles 0..99 answered, cycle 100's SYNC found the firmware dead"
