"""The soak without a bus. One piece at a time: frames packed from the EDS (checked against the DBC
with cantools, independently of the struct layouts that packed them), the seeded fault plan, the
memory verdict, the firmware's stop line, the checker fed results and frames by hand. Then the
whole soak, on the engine's real lockstep driver, against an in-process fake firmware that is
the driver's node and link and answers synchronously (and can be told to misbehave)."""

from __future__ import annotations

import argparse
import json
import math
import struct
from collections import Counter, deque
from operator import attrgetter
from pathlib import Path

import canopen
import cantools
import pytest

from boardproto.cia301 import (
    EMCY_ERROR_RESET,
    HEARTBEAT_STATE_MASK,
    NMT_COB_ID,
    PDO_EXTENSION_OFFSET,
    RPDO_FUNCTIONS,
    SYNC_COB_ID,
    TIME_COB_ID,
    TPDO_FUNCTIONS,
    NmtCommand,
    NmtState,
    SdoAbortCode,
    cob_id,
    emcy_cob_id,
    heartbeat_cob_id,
    sdo_request_cob_id,
    sdo_response_cob_id,
)
from boardproto.table import ErrorRegisterBit
from hilrig.apps.soak.checker import CycleChecker, SoakError, Tally
from hilrig.apps.soak.fault_plan import FaultPlan, PlannedFault, SoakFault, min_fault_interval, plan_faults
from hilrig.apps.soak.layout import (
    EMCY_PDO_LENGTH,
    EMCY_STALE_SENSOR,
    RPDO_COMMUNICATION_BASE,
    STALE_ENCODER_BITS,
    STALE_ENCODER_FLAGS,
    SensorPattern,
    SoakLayout,
    load_layout,
)
from hilrig.apps.soak.memory import ProcessSample, memory_verdict
from hilrig.apps.soak.report import RunStatus, build_report, compare_counters, thin, write_json_atomic
from hilrig.apps.soak.soak import Soak
from hilrig.engine.driver import CycleResult
from hilrig.engine.lockstep import CycleProblem
from hilrig.engine.rig import DEFAULT_EDS_PATH
from hilrig.errors import SdoAbortError
from hilrig.plants.interface import Plant
from hilrig.session.firmware import parse_stop_line
from hilrig.table import FaultFlags, RigTable
from hilrig.wire.node import explain_abort
from hilrig.wire.transport import PdoDirection, can_frame, compile_pdos, parse_frame

NODE_ID = 0x10
DBC_PATH = DEFAULT_EDS_PATH.with_name("board.dbc")
STOP_LINE = (
    "joint-firmware: stopped after 3000 cycles; overruns 0; frames received 9001, ignored 2, "
    "malformed 0, SDO aborts 0, RPDO length errors 1, TPDOs sent 21300, EMCY 4, send failures 0, "
    "bus error frames 0, receive overruns 0, board refused writes 0"
)


@pytest.fixture(scope="module")
def layout() -> SoakLayout:
    return load_layout(DEFAULT_EDS_PATH, NODE_ID)


@pytest.fixture(scope="module")
def dbc() -> cantools.database.can.Database:
    return cantools.database.load_file(str(DBC_PATH))


# --- Frames against the EDS and the DBC ----------------------------------------------------
def test_layout_is_the_eds_default_mapping(layout: SoakLayout) -> None:
    assert layout.sensor.label == "RPDO1 (0x210)"
    assert layout.sensor.codec.format == "<HHHh"
    assert layout.setpoint.names == ("velocity_setpoint", "torque_setpoint")
    tpdo1_to_4 = [cob_id(tpdo, NODE_ID) for tpdo in TPDO_FUNCTIONS]
    tpdo5_to_8 = [cob + PDO_EXTENSION_OFFSET for cob in tpdo1_to_4]  # the predefined set's extension
    assert [p.cob_id for p in layout.tpdos] == tpdo1_to_4 + tpdo5_to_8
    assert layout.status.label == "TPDO6 (0x2D0)"
    assert [p.transmission_type for p in layout.tpdos] == [1] * 7 + [10]
    assert layout.tpdos[0].length == 3  # I16 motor_duty + U8 led_pattern
    assert (layout.emcy_cob_id, layout.heartbeat_cob_id) == (emcy_cob_id(NODE_ID), heartbeat_cob_id(NODE_ID))
    assert layout.encoder_stale_cycles == 20


def test_unknown_cob_ids_avoid_everything_the_node_uses(layout: SoakLayout) -> None:
    unknown = set(layout.unknown_cob_ids())
    node_ids = {
        NMT_COB_ID,
        SYNC_COB_ID,
        emcy_cob_id(NODE_ID),
        TIME_COB_ID,
        sdo_response_cob_id(NODE_ID),
        sdo_request_cob_id(NODE_ID),
        heartbeat_cob_id(NODE_ID),
        *(cob_id(rpdo, NODE_ID) for rpdo in RPDO_FUNCTIONS),
    }
    assert not unknown & (node_ids | {p.cob_id for p in layout.tpdos})
    assert 0x123 in unknown


def test_sensor_frame_decodes_with_the_dbc_to_the_pattern(layout: SoakLayout, dbc) -> None:
    pattern = SensorPattern(layout, period_us=1000)
    for cycle in (1, 2, 2621, 2622, 1_000_000):  # 2622 * 25 wraps the 16-bit motor counter
        raw = pattern.raw(cycle)
        # As the engine's driver packs it: the RPDO's values by name from the raw sensors.
        cob_id, data = parse_frame(layout.sensor.frame(attrgetter(*layout.sensor.names)(raw)))
        decoded = dbc.decode_message(cob_id, data)
        motor, output, adc, current = (
            raw.motor_encoder_counts, raw.output_encoder_counts, raw.thermistor_adc, raw.motor_current_adc
        )  # fmt: skip
        assert decoded == {
            "motor_encoder_counts": motor,
            "output_encoder_counts": output,
            "thermistor_adc": adc,
            "motor_current_adc": current,
        }
        assert motor == cycle * 25 % 65536
        assert output == cycle * 2 % 65536  # 25 counts * 16384 / (4096 * gear 50) = 2 per cycle
    assert pattern.thermistor_adc == 2048  # 10 kOhm NTC at 25 degC against the 10 kOhm pull-up
    assert pattern.motor_velocity_rad_s == pytest.approx(25 / 4096 * 2 * math.pi * 1000)


def test_the_pattern_is_the_drivers_plant_without_physics(layout: SoakLayout) -> None:
    pattern = SensorPattern(layout, period_us=1000)
    assert isinstance(pattern, Plant)
    state = pattern.truth()
    pattern.cycle = 7
    assert pattern.sense() == pattern.raw(7)
    pattern.apply((5000,))
    pattern.step(1e-3)
    assert pattern.truth() is state  # nothing moves: the values follow `cycle` only
    assert state.motor_velocity_rad_s == pattern.motor_velocity_rad_s


def test_status_and_sdo_bytes_decode_with_the_dbc(layout: SoakLayout, dbc) -> None:
    status = layout.status.cob_id
    decoded = dbc.decode_message(status, layout.status_bytes(STALE_ENCODER_FLAGS), decode_choices=False)
    both_encoders = FaultFlags.MOTOR_ENCODER_STALE | FaultFlags.OUTPUT_ENCODER_STALE
    latched = {"safe_state": 1.0, "fault_flags": float(both_encoders)}
    assert decoded == latched
    assert dbc.decode_message(status, layout.status_bytes(0), decode_choices=False) == {
        "safe_state": 0.0,
        "fault_flags": 0.0,
    }
    reads = {o.label: o for o in layout.sdo_reads}
    assert struct.unpack("<f", reads["encoder_stale_cycles"].expected) == (20.0,)
    assert struct.unpack("<H", reads["heartbeat time"].expected) == (100,)
    index, subindex, data = layout.fault_clear
    assert (index, subindex, struct.unpack("<f", data)) == (0x2404, 0, (1.0,))


def test_can_frame_round_trip_and_limits() -> None:
    assert parse_frame(can_frame(0x123, b"\x01\x02")) == (0x123, b"\x01\x02")
    assert len(can_frame(0x7FF, bytes(8))) == 16
    with pytest.raises(ValueError, match="11-bit"):
        can_frame(0x800, b"")
    with pytest.raises(ValueError, match="8 bytes"):
        can_frame(0x123, bytes(9))


# --- Fault plan ---------------------------------------------------------------------------
def test_fault_plan_is_determined_by_its_seed(layout: SoakLayout) -> None:
    first = plan_faults(1_000_000, 10_000, 11, layout)
    assert first == plan_faults(1_000_000, 10_000, 11, layout)
    assert first != plan_faults(1_000_000, 10_000, 12, layout)
    assert len(first.faults) == 99
    assert set(first.counts()) == {k.value for k in SoakFault}


def test_fault_plan_spacing_first_round_and_warmup(layout: SoakLayout) -> None:
    interval = 1000
    plan = plan_faults(100_000, interval, 3, layout)
    kinds = [f.kind for f in plan.faults]
    assert sorted(kinds[: len(SoakFault)]) == sorted(SoakFault)  # every kind once, first
    for n, fault in enumerate(plan.faults, start=1):
        assert abs(fault.cycle - n * interval) <= interval // 4
    assert plan.faults[-1].cycle + interval // 4 <= 100_000
    assert plan.warmup_cycle == plan.faults[len(SoakFault) - 1].cycle + interval // 2
    for fault in plan.faults:
        if fault.kind is SoakFault.MALFORMED_RPDO:
            assert 0 <= fault.arg < layout.sensor.length
        elif fault.kind is SoakFault.UNKNOWN_COB_ID:
            assert fault.arg in layout.unknown_cob_ids()
        elif fault.kind in (SoakFault.STALE_SENSOR, SoakFault.NMT_STOP_START):
            assert 1 <= fault.arg <= 5


def test_fault_plan_refuses_overlapping_episodes_and_handles_short_runs(layout: SoakLayout) -> None:
    with pytest.raises(ValueError, match="fault interval"):
        plan_faults(10_000, min_fault_interval(layout) - 1, 1, layout)
    short = plan_faults(2500, 1000, 1, layout)
    assert len(short.faults) == 2
    assert short.warmup_cycle == 1250  # the first round does not fit: half the run


# --- Memory -------------------------------------------------------------------------------
def _samples(
    rss: list[int], fds: list[int] | None = None, exact: list[int] | None = None
) -> list[ProcessSample]:
    fds = fds or [5] * len(rss)
    exact = exact or rss
    return [
        ProcessSample(i * 1000, float(i), r, r // 2, e, f, 0.1 * i)
        for i, (r, f, e) in enumerate(zip(rss, fds, exact, strict=True))
    ]


def test_memory_flat_after_warmup_passes_even_if_warmup_grew() -> None:
    verdict = memory_verdict(_samples([9000, 12000, 12288, 12288, 12300]), warmup_cycle=1500, bound_kib=64)
    assert verdict.ok is True
    assert (verdict.baseline_cycle, verdict.rss_warmup_kib, verdict.rss_end_kib) == (2000, 12288, 12300)
    assert verdict.growth_kib == 12 and verdict.rss_start_kib == 9000


def test_memory_growth_beyond_the_bound_fails() -> None:
    verdict = memory_verdict(_samples([12000, 12000, 12040, 12080]), warmup_cycle=0, bound_kib=64)
    assert verdict.ok is False
    assert "VmRSS grew 80 KiB after warm-up, bound 64 KiB" in verdict.reason


def test_memory_exact_rss_growth_fails_even_when_vmrss_lags() -> None:
    verdict = memory_verdict(
        _samples([12000, 12000, 12000], exact=[12000, 12100, 12200]), warmup_cycle=0, bound_kib=64
    )
    assert verdict.ok is False and "exact Rss grew 200 KiB" in verdict.reason


def test_memory_fd_change_fails() -> None:
    verdict = memory_verdict(_samples([12000] * 4, fds=[5, 5, 6, 5]), warmup_cycle=0, bound_kib=64)
    assert verdict.ok is False
    assert "open fds went from 5 to 6 at cycle 2000" in verdict.reason


def test_memory_without_two_samples_after_warmup_is_inconclusive() -> None:
    verdict = memory_verdict(_samples([12000, 12000, 12000]), warmup_cycle=2000, bound_kib=64)
    assert verdict.ok is None and "inconclusive" in verdict.reason
    assert memory_verdict([], warmup_cycle=0, bound_kib=64).ok is None


def test_thin_keeps_first_and_last() -> None:
    assert thin(list(range(10)), 20) == list(range(10))
    thinned = thin(list(range(1001)), 5)
    assert thinned == [0, 250, 500, 750, 1000]


# --- The firmware's stop line -------------------------------------------------------------
def test_stop_line_parses_and_compares() -> None:
    line, counters = parse_stop_line("joint-firmware: node 16 ...\n" + STOP_LINE + "\n")
    assert line == STOP_LINE
    assert counters["cycles"] == 3000 and counters["frames received"] == 9001
    assert counters["RPDO length errors"] == 1 and counters["board refused writes"] == 0
    tally = Tally(
        syncs_operational=3000, frames_sent=9001, ignored_expected=2, length_errors=1,
        tpdos_received=21300, emcy_received=4,
    )  # fmt: skip
    assert compare_counters(tally.expected_counters(), counters) == []
    tally.frames_sent += 1
    assert compare_counters(tally.expected_counters(), counters) == [
        "firmware: frames received 9001, expected 9002"
    ]
    assert parse_stop_line("crashed") is None
    assert compare_counters({"EMCY": 0}, {}) == ["firmware stop line has no 'EMCY' counter"]


# --- The checker, one piece: results, problems and frames handed to it by hand --------------
def _result(layout: SoakLayout, status: tuple[float, ...], *, sent: int = 2) -> CycleResult:
    """A cycle's result as the lockstep driver hands it over: TPDO values by COB-ID."""
    got = {p.cob_id: tuple(0 for _ in p.names) for p in layout.tpdos}
    got[layout.status.cob_id] = status
    rows = tuple((layout.setpoint, (0.0, 0.0)) for _ in range(sent))
    return CycleResult(1, 0.001, 2, None, got, 0.0, rows, None, {p.cob_id: p for p in layout.tpdos})


def test_checker_tallies_a_cycle_and_refuses_the_wrong_status(layout: SoakLayout) -> None:
    checker = CycleChecker(layout)
    checker.cycle = 1
    checker.operational_cycle(_result(layout, checker.status_values(0)))
    tally = checker.tally
    assert (tally.syncs_operational, tally.frames_sent, tally.tpdos_received) == (1, 3, 8)
    assert checker.problems == []
    checker.cycle = 2
    checker.operational_cycle(_result(layout, checker.status_values(0)), status=checker.latched_status)
    assert checker.problems == [
        "cycle 2: TPDO6 (0x2D0): expected {'safe_state': 1.0, 'fault_flags': 3.0}, got "
        "{'safe_state': 0.0, 'fault_flags': 0.0}"
    ]


def test_checker_reads_emcy_and_heartbeat_frames_by_the_cia301_layout(layout: SoakLayout) -> None:
    checker = CycleChecker(layout)
    checker.cycle = 5
    about = layout.stale_about[0]
    # The error code, the error register, the object it is about in the manufacturer field.
    checker.on_emcy(layout.emcy_cob_id, struct.pack("<HBH3x", EMCY_STALE_SENSOR, 1, about))
    toggle = HEARTBEAT_STATE_MASK + 1  # node guarding's toggle bit, above the state's
    checker.on_heartbeat(layout.heartbeat_cob_id, bytes([toggle | NmtState.OPERATIONAL]))
    assert checker.emcy_log == [(5, EMCY_STALE_SENSOR, about)] and checker.tally.emcy_received == 1
    assert checker.heartbeat_states == {NmtState.OPERATIONAL: 1}
    checker.check_emcy(())
    got = f"0x{EMCY_STALE_SENSOR:04X} about 0x{about:04X}"
    assert checker.problems == [f"cycle 5: EMCY: expected none, got {got}"]


def test_checker_counts_refused_frames_and_gives_up_after_too_many_lost_cycles(layout: SoakLayout) -> None:
    checker = CycleChecker(layout, max_lost=1)
    tpdo3 = layout.tpdos[2]
    checker.on_problem(CycleProblem(0, 0.0, "TPDO3 (0x390) arrived twice", refused=tpdo3))
    assert checker.tally.tpdos_received == 1 and checker.lost_problem is None
    lost = CycleProblem(0, 0.0, "TPDO3 (0x390) did not arrive within 10 s", missing=(tpdo3,))
    checker.on_problem(lost)
    assert checker.lost_problem is lost
    checker.lost_cycle(lost, 1, [tpdo3])
    assert checker.lost_problem is None
    assert checker.lost[0].late == ("TPDO3 (0x390)",) and checker.tally.tpdos_received == 2
    with pytest.raises(SoakError, match="2 lost cycles"):
        checker.lost_cycle(lost, 1, [])


# --- The soak on the engine's lockstep driver, against a fake firmware ---------------------
MISSING_OBJECT = (0x2FFF, 0)
"""An object the fake firmware does not have: a download to it is aborted."""


class FakeFirmware:
    """Answers like joint-firmware in lockstep mode, synchronously, frame by frame: NMT, one
    cycle per SYNC with the TPDOs due, RPDO length errors, encoder staleness latched in
    fault_flags and cleared by fault_clear, expedited SDO, and the stop line's counters.

    It is the lockstep driver's node (what of `BoardNode` the driver and the soak use: the PDO
    mapping from the EDS, SDO, NMT) and its frame link (`hilrig.wire.transport.FrameLink`).

    Misbehaviour on request: `drop` leaves one TPDO out at a cycle, `extra` sends one that is
    not due, `answer_while_stopped` answers SYNCs in NMT stopped, `stale_limit` latches at
    another count than the EDS says."""

    last_heartbeat = None

    def __init__(
        self,
        layout: SoakLayout,
        *,
        drop: tuple[int, int] | None = None,
        extra: tuple[int, int] | None = None,
        answer_while_stopped: bool = False,
        stale_limit: int | None = None,
    ) -> None:
        self.layout = layout
        self.node_id = layout.node_id
        self.table = RigTable.load()
        network = canopen.Network()  # never connected: the PDO maps from the EDS
        remote = canopen.RemoteNode(layout.node_id, str(DEFAULT_EDS_PATH))
        network.add_node(remote)
        remote.rpdo.read(from_od=True)
        remote.tpdo.read(from_od=True)
        self.rpdos = compile_pdos(PdoDirection.RPDO, remote.rpdo.map)
        self.tpdos = compile_pdos(PdoDirection.TPDO, remote.tpdo.map)
        self.receive_ids: list[int] = []
        self.drop = drop  # (cycle, TPDO number)
        self.extra = extra  # (cycle, TPDO number): sent although not due
        self.answer_while_stopped = answer_while_stopped
        self.stale_limit = stale_limit if stale_limit is not None else layout.encoder_stale_cycles
        self.out: deque[bytes] = deque([can_frame(layout.heartbeat_cob_id, bytes([NmtState.INITIALISING]))])
        self.state = "pre-operational"
        self.cycle = 0
        self.sync_number = 0
        self.counters: Counter[str] = Counter()
        self.sensor_pending = False
        self.last_sensor_cycle = 0
        self.flags = 0
        self.clear_requested = False
        self.length_error = False
        self.objects = {(o.index, o.subindex): o.expected for o in layout.sdo_reads}
        # What Node::accepted_ids gives the default configuration (the SDO request goes through
        # upload/download below, NMT through nmt); no 0x1016 entry is used in the soak.
        self.accepted = {NMT_COB_ID, SYNC_COB_ID, *(cob_id(rpdo, layout.node_id) for rpdo in RPDO_FUNCTIONS)}
        pattern = SensorPattern(layout, period_us=1000)
        self.velocities = {
            "motor_velocity": pattern.motor_velocity_rad_s,
            "output_velocity": pattern.output_velocity_rad_s,
        }

    # What the driver and the soak use of BoardNode.
    def read_pdo_configuration(self, *, from_node: bool) -> None:
        assert not from_node  # an SDO read of the mapping would be frames the tally misses

    def open_link(self, receive_ids: list[int]) -> FakeFirmware:
        self.receive_ids = receive_ids
        return self

    def emcy_received(self, data: bytes) -> None:
        pass

    def nmt(self, command: NmtCommand) -> None:
        self.counters["frames received"] += 1
        self.state = {NmtCommand.START: "operational", NmtCommand.STOP: "stopped"}[command]
        self.sync_number = 0

    def upload(self, index: int, subindex: int, what: str | None = None) -> bytes:
        self.counters["frames received"] += 1
        return self.objects[(index, subindex)]

    def download(self, index: int, subindex: int, data: bytes, what: str | None = None) -> None:
        self.counters["frames received"] += 1
        if (index, subindex) == MISSING_OBJECT:
            self.counters["SDO aborts"] += 1
            code = SdoAbortCode.OBJECT_DOES_NOT_EXIST
            raise SdoAbortError(f"{what}: {explain_abort(code)}", code)
        self.objects[(index, subindex)] = data
        if (index, subindex) == self.layout.fault_clear[:2]:
            self.clear_requested = True

    # The FrameLink (hilrig.wire.transport).
    def send(self, frame: bytes) -> None:
        cob_id, data = parse_frame(frame)
        if cob_id not in self.accepted:  # the firmware's acceptance filter: never received
            return
        self.counters["frames received"] += 1
        self._process(cob_id, data)

    def recv(self, timeout_s: float) -> tuple[int, bytes] | None:
        return parse_frame(self.out.popleft()) if self.out else None

    def close(self) -> None:
        pass

    def stop_line(self) -> str:
        c = self.counters
        return (
            f"joint-firmware: stopped after {self.cycle} cycles; overruns 0; frames received "
            f"{c['frames received']}, ignored {c['ignored']}, malformed 0, SDO aborts {c['SDO aborts']}, "
            f"RPDO length errors {c['RPDO length errors']}, TPDOs sent {c['TPDOs sent']}, EMCY {c['EMCY']}, "
            "send failures 0, bus error frames 0, receive overruns 0, board refused writes 0"
        )

    def _emit(self, cob_id: int, data: bytes) -> None:
        self.out.append(can_frame(cob_id, data))

    def _emcy(self, code: int, about: int) -> None:
        self.counters["EMCY"] += 1
        register = ErrorRegisterBit.GENERIC if code != EMCY_ERROR_RESET else 0
        self._emit(self.layout.emcy_cob_id, struct.pack("<HBH3x", code, register, about))

    def _process(self, cob_id: int, data: bytes) -> None:
        layout = self.layout
        if self.state == "stopped" and not (cob_id == SYNC_COB_ID and self.answer_while_stopped):
            self.counters["ignored"] += 1
            return
        if cob_id == SYNC_COB_ID:
            self._sync()
        elif cob_id == layout.sensor.cob_id:
            if len(data) < layout.sensor.length:
                self.counters["RPDO length errors"] += 1
                if not self.length_error:
                    self._emcy(EMCY_PDO_LENGTH, RPDO_COMMUNICATION_BASE + layout.sensor.number - 1)
                self.length_error = True
                return
            if self.length_error:
                self._emcy(EMCY_ERROR_RESET, 0)
                self.length_error = False
            self.sensor_pending = True
        elif cob_id == layout.setpoint.cob_id:
            pass
        else:
            self.counters["ignored"] += 1

    def _sync(self) -> None:
        self.cycle += 1
        if self.sensor_pending:
            self.last_sensor_cycle = self.cycle
            self.sensor_pending = False
        causes = STALE_ENCODER_FLAGS if self.cycle - self.last_sensor_cycle >= self.stale_limit else 0
        if self.clear_requested:
            for _ in range(bin(self.flags & ~causes).count("1")):
                self._emcy(EMCY_ERROR_RESET, 0)
            self.flags &= causes
            self.clear_requested = False
        for bit, about in zip(STALE_ENCODER_BITS, self.layout.stale_about, strict=True):
            if causes & ~self.flags & bit.mask:
                self._emcy(EMCY_STALE_SENSOR, about)
        self.flags |= causes
        self.sync_number += 1
        due = [p for p in self.layout.tpdos if p.due_at_sync(self.sync_number)]
        if self.extra is not None and self.extra[0] == self.cycle:
            due.append(next(p for p in self.layout.tpdos if p.number == self.extra[1]))
        for pdo in due:
            if self.drop == (self.cycle, pdo.number):
                continue
            payload = self.layout.status_bytes(self.flags) if pdo is self.layout.status else bytes(pdo.length)
            if "motor_velocity" in pdo.names:  # the exact speeds of the sensor pattern
                payload = pdo.pack_named({n: self.velocities.get(n, 0.0) for n in pdo.names})
            self.counters["TPDOs sent"] += 1
            self._emit(pdo.cob_id, payload)


def _flat_probe(cycle: int, elapsed: float) -> ProcessSample:
    return ProcessSample(cycle, elapsed, 20_000, 8_000, 20_000, 5, cycle * 1e-4)


def _soak(layout: SoakLayout, fake: FakeFirmware, plan: FaultPlan, **kwargs) -> Soak:
    return Soak(fake, layout, plan, **kwargs)  # type: ignore[arg-type]  # the fake is the node


def _run(
    layout: SoakLayout, fake: FakeFirmware, plan: FaultPlan, cycles: int, **kwargs
) -> tuple[Soak, dict[str, int]]:
    soak = _soak(layout, fake, plan, probe=_flat_probe, sample_every=100, **kwargs)
    soak.start()
    soak.run(cycles)
    soak.finish()
    _, counters = parse_stop_line(fake.stop_line())
    return soak, counters


def test_clean_run_against_the_fake_passes_every_check(layout: SoakLayout) -> None:
    plan = plan_faults(3000, 200, 5, layout)
    fake = FakeFirmware(layout)
    soak, counters = _run(layout, fake, plan, 3000)
    checker = soak.checker
    assert checker.problems == [] and checker.lost == []
    assert soak.cycle == 3000 == fake.cycle
    assert compare_counters(checker.tally.expected_counters(), counters) == []
    assert sum(soak.faults_done.values()) == len(plan.faults) == 14
    assert set(soak.faults_done) == {k.value for k in SoakFault}
    assert checker.tally.syncs_stopped > 0 and checker.tally.length_errors > 0
    assert [s.cycle for s in soak.samples][:3] == [0, 100, 200] and soak.samples[-1].cycle == 3000
    codes = Counter(code for _, code, _ in checker.emcy_log)
    stale, malformed = (
        soak.faults_done[SoakFault.STALE_SENSOR],
        soak.faults_done[SoakFault.MALFORMED_RPDO],
    )
    assert codes == {
        EMCY_STALE_SENSOR: 2 * stale,
        EMCY_PDO_LENGTH: malformed,
        EMCY_ERROR_RESET: 2 * stale + malformed,
    }
    # The engine's driver ran every SYNC (stopped ones too), kept no history, heard the heartbeat.
    assert soak.driver.cycle == 3000 + checker.tally.syncs_stopped
    assert soak.driver.history.cycles == 0 and checker.heartbeat_states == {NmtState.INITIALISING: 1}
    assert {layout.emcy_cob_id, layout.heartbeat_cob_id} <= set(fake.receive_ids)


def test_a_missing_tpdo_is_a_lost_cycle_and_the_run_goes_on(layout: SoakLayout) -> None:
    fake = FakeFirmware(layout, drop=(57, 3))
    soak, counters = _run(layout, fake, FaultPlan((), 0, 0, 1000), 200)
    checker = soak.checker
    assert [(c.cycle, c.missing) for c in checker.lost] == [(57, ("TPDO3 (0x390)",))]
    assert checker.lost[0].received == tuple(p.label for p in layout.tpdos[:7] if p.number != 3)
    assert soak.cycle == 200 and compare_counters(checker.tally.expected_counters(), counters) == []
    assert checker.problems == ["cycle 57: lost: TPDO3 (0x390) did not arrive within 10 s"]


def test_a_tpdo_that_is_not_due_is_a_problem_not_a_lost_cycle(layout: SoakLayout) -> None:
    soak, counters = _run(layout, FakeFirmware(layout, extra=(33, 8)), FaultPlan((), 0, 0, 1000), 100)
    assert soak.checker.lost == []
    # It trails cycle 33's due frames; the engine takes what is queued behind them.
    assert soak.checker.problems == [
        "cycle 33: TPDO8 (0x4D0) arrived but is not due at SYNC 33 since operational (transmission type 10)"
    ]
    assert compare_counters(soak.checker.tally.expected_counters(), counters) == []


def test_tpdos_answered_while_stopped_are_caught(layout: SoakLayout) -> None:
    plan = FaultPlan((PlannedFault(50, SoakFault.NMT_STOP_START, 2),), 0, 0, 1000)
    fake = FakeFirmware(layout, answer_while_stopped=True)
    soak, counters = _run(layout, fake, plan, 100)
    assert any("arrived while the node is not operational" in p for p in soak.checker.problems)
    assert soak.checker.tally.tpdos_received == counters["TPDOs sent"]


def test_a_latch_at_the_wrong_cycle_is_caught(layout: SoakLayout) -> None:
    plan = FaultPlan((PlannedFault(50, SoakFault.STALE_SENSOR, 2),), 0, 0, 1000)
    soak, _ = _run(layout, FakeFirmware(layout, stale_limit=layout.encoder_stale_cycles + 1), plan, 100)
    expected = {"safe_state": 1.0, "fault_flags": float(STALE_ENCODER_FLAGS)}
    assert soak.checker.problems and f"TPDO6 (0x2D0): expected {expected}" in soak.checker.problems[0]


def test_a_wrong_sdo_answer_and_an_abort_are_caught(layout: SoakLayout) -> None:
    fake = FakeFirmware(layout)
    vendor = layout.sdo_reads[0]
    fake.objects[(vendor.index, vendor.subindex)] = b"\x01\x02\x03\x04"
    plan = FaultPlan((PlannedFault(20, SoakFault.SDO_UPLOAD, 0),), 0, 0, 1000)
    soak = _soak(layout, fake, plan)
    soak.start()
    soak.run(30)
    assert soak.checker.problems == [
        "cycle 19: SDO upload vendor id 0x1018:1: expected 004c4948, got 01020304"
    ]
    assert not soak.sdo_download("nothing", *MISSING_OBJECT, b"\x00")
    missing = explain_abort(SdoAbortCode.OBJECT_DOES_NOT_EXIST)
    assert soak.checker.problems[-1] == f"cycle 30: SDO download nothing: {missing}"


def test_stop_request_ends_the_run_early(layout: SoakLayout) -> None:
    fake = FakeFirmware(layout)
    soak = _soak(layout, fake, FaultPlan((), 0, 0, 1000), stop_requested=lambda: True)
    soak.start()
    soak.run(10_000)
    assert soak.stopped_by_request and soak.cycle == 256


def _args(**overrides) -> argparse.Namespace:
    values = {
        "cycles": 300,
        "sample_every": 100,
        "rss_bound_kib": 64,
        "pin": False,
        "cpu": 0,
        "period_us": 1000,
        "thp": "left as the system has it",
    }
    return argparse.Namespace(**(values | overrides))


def test_report_verdicts(layout: SoakLayout, tmp_path: Path) -> None:
    fake = FakeFirmware(layout, drop=(99, 1))
    plan = FaultPlan((), 0, 0, 1000)
    soak, counters = _run(layout, fake, plan, 300)
    firmware = {"stop_line": fake.stop_line(), "counters": counters}
    common = {
        "plan": plan,
        "error": None,
        "bus": {},
        "started_wall": 0.0,
        "duration_s": 5.0,
        "cycling_s": 3.0,
        "driver_cpu_s": 1.0,
    }
    report = build_report(args=_args(), soak=soak, status=RunStatus.PASSED, firmware=firmware, **common)
    assert report["status"] == "failed" and report["lost_cycles"] == 1
    assert report["failures"] == ["1 lost cycle(s)", "1 check(s) failed"]
    assert report["memory"]["ok"] is True and report["memory"]["rss_end_kib"] == 20_000
    assert report["rate_cycles_per_s"] == 100.0
    assert report["driver"]["heartbeat_states"] == {"0x00": 1}

    clean, counters = _run(layout, FakeFirmware(layout), plan, 300)
    firmware = {"stop_line": "...", "counters": counters}
    report = build_report(args=_args(), soak=clean, status=RunStatus.INTERRUPTED, firmware=firmware, **common)
    assert report["status"] == "interrupted" and report["failures"] == []
    counters["cycles"] += 1
    report = build_report(args=_args(), soak=clean, status=RunStatus.PASSED, firmware=firmware, **common)
    assert report["failures"] == ["firmware counters disagree: firmware: cycles 301, expected 300"]

    path = tmp_path / "soak" / "report.json"
    write_json_atomic(path, report)
    assert json.loads(path.read_text())["cycles"] == 300
    assert [p.name for p in path.parent.iterdir()] == ["report.json"]


def test_a_velocity_estimate_off_by_more_than_the_goal_fails_the_run(layout: SoakLayout) -> None:
    fake = FakeFirmware(layout)
    fake.velocities["motor_velocity"] *= 1.002  # 0.2 %: what float32 angles gave after 100k cycles
    soak, counters = _run(layout, fake, FaultPlan((), 0, 0, 1000), 300)
    firmware = {"stop_line": fake.stop_line(), "counters": counters}
    report = build_report(
        args=_args(), soak=soak, plan=FaultPlan((), 0, 0, 1000), status=RunStatus.PASSED, error=None,
        firmware=firmware, bus={}, started_wall=0.0, duration_s=1.0, driver_cpu_s=0.1,
    )  # fmt: skip
    assert report["status"] == "failed"
    assert report["velocity"]["first_tenth"]["output_max_error_pct"] < 1e-4
    assert any(f.startswith("velocity estimate: motor off by 0.2000") for f in report["failures"])
