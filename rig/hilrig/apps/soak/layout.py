"""What the soak sends and what it expects, frozen once from the generated EDS: the PDO layout
(`load_layout`: the sensor and setpoint RPDOs, the cyclic TPDOs, the status TPDO, the objects the
SDO fault reads), the EMCYs the faults must bring, and the sensor values of each cycle
(`SensorPattern`: a constant rotation the checks can predict exactly, no physics; it stands in
for the plant and the sensors of the engine's lockstep driver).

The PDOs are compiled into the same codecs the Rig uses (`hilrig.wire.transport.compile_pdos`);
which TPDOs are due at which SYNC is the engine's to know (`hilrig.engine.driver.Driver`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import canopen
import numpy as np

from boardproto.cia301 import (
    NMT_COB_ID,
    SYNC_COB_ID,
    TIME_COB_ID,
    FunctionCode,
    emcy_cob_id,
    heartbeat_cob_id,
    sdo_request_cob_id,
    sdo_response_cob_id,
)
from boardproto.cia305 import MASTER_COB_ID as LSS_MASTER_COB_ID
from hilrig import resources
from hilrig.errors import PdoMappingError
from hilrig.plants import (
    ENCODER_MODULUS,
    STATE_FIELDS,
    JointParams,
    JointPlant,
    JointState,
    RawSensors,
    state_matrix,
    thermistor_adc,
)
from hilrig.plants.interface import Value
from hilrig.plants.joint import ACTUATOR_FIELD
from hilrig.table import BOARD_TABLE, ControlMode, EmcyCode, FaultFlags, RigTable
from hilrig.wire.transport import PdoDirection, PdoLayout, compile_pdos

DEFAULT_EDS_PATH = resources.DEFAULT_EDS
VELOCITY_MODE = float(ControlMode.VELOCITY)
"""The velocity loop (board.toml), so the controllers and the watchdog run."""
MOTOR_COUNTS_PER_CYCLE = 25
"""The sensor pattern turns the motor encoder by this many counts per cycle (38 rad/s at 1 kHz)."""
ENCODER_MASK = ENCODER_MODULUS - 1
"""Both encoders' 16-bit counters wrap (the firmware unwraps them)."""
STALE_ENCODER_BITS = tuple(
    BOARD_TABLE.bitset("fault_flags").bit(name) for name in ("motor_encoder_stale", "output_encoder_stale")
)
"""The fault bits the stale-sensor fault latches (the soak withholds both encoders), with the EMCY
each raises and the object it names (board.toml)."""
STALE_ENCODER_FLAGS = FaultFlags.MOTOR_ENCODER_STALE | FaultFlags.OUTPUT_ENCODER_STALE
MAX_EXTRA_STALE_CYCLES = 5

EMCY_STALE_SENSOR = EmcyCode[(STALE_ENCODER_BITS[0].emcy or "").upper()]
EMCY_PDO_LENGTH = EmcyCode.PDO_LENGTH_ERROR
RPDO_COMMUNICATION_BASE = BOARD_TABLE.rpdo(1).communication_index


# --- The PDO layout, from the EDS --------------------------------------------------------------
@dataclass(frozen=True)
class SdoObject:
    """An object the soak reads over SDO, with the bytes the node must answer."""

    label: str
    index: int
    subindex: int
    expected: bytes


@dataclass(frozen=True)
class SoakLayout:
    node_id: int
    sensor: PdoLayout
    setpoint: PdoLayout
    tpdos: tuple[PdoLayout, ...]
    """Enabled synchronous cyclic TPDOs (types 1..240, `PdoLayout.is_cyclic`)."""
    status: PdoLayout
    """The TPDO carrying safe_state and fault_flags."""
    encoder_stale_cycles: int
    thermistor_stale_cycles: int
    stale_about: tuple[int, ...]
    """Object indexes the stale-sensor EMCYs name (motor_position, output_position)."""
    fault_clear: tuple[int, int, bytes]
    """index, subindex and the bytes of fault_clear = 1."""
    control_mode: tuple[int, int, bytes]
    """index, subindex and the bytes of control_mode = VELOCITY_MODE."""
    sdo_reads: tuple[SdoObject, ...]
    defaults: dict[str, float]
    """EDS defaults of the parameters the sensor pattern needs (gear ratio, counts per rev)."""
    used_cob_ids: frozenset[int]

    @property
    def emcy_cob_id(self) -> int:
        return emcy_cob_id(self.node_id)

    @property
    def sdo_response_cob_id(self) -> int:
        return sdo_response_cob_id(self.node_id)

    @property
    def sdo_request_cob_id(self) -> int:
        return sdo_request_cob_id(self.node_id)

    @property
    def heartbeat_cob_id(self) -> int:
        return heartbeat_cob_id(self.node_id)

    def status_bytes(self, fault_flags: int) -> bytes:
        """The status TPDO's payload for a latched fault mask (safe_state follows it)."""
        return self.status.pack_named(
            {"safe_state": float(bool(fault_flags)), "fault_flags": float(fault_flags)}
        )

    def unknown_cob_ids(self) -> list[int]:
        """11-bit COB-IDs this node neither uses nor listens to (NMT, SYNC, TIME excluded)."""
        return [i for i in range(1, 0x800) if i not in self.used_cob_ids]


def load_layout(eds: str | Path, node_id: int, table: RigTable | None = None) -> SoakLayout:
    """Read the EDS once (canopen, no bus) and freeze what the soak sends and expects.

    PdoMappingError says what is missing when the default mapping lacks the sensor inputs, the
    setpoint stream or the status TPDO the soak relies on."""
    table = table if table is not None else RigTable.load()
    network = canopen.Network()  # never connected: it only gives the PDO maps somewhere to live
    node = canopen.RemoteNode(node_id, str(eds))
    network.add_node(node)
    node.rpdo.read(from_od=True)
    node.tpdo.read(from_od=True)
    od = node.object_dictionary
    rpdos = [p for p in compile_pdos(PdoDirection.RPDO, node.rpdo.map).values() if p.enabled and p.names]
    tpdos = [p for p in compile_pdos(PdoDirection.TPDO, node.tpdo.map).values() if p.enabled and p.names]
    inputs = {io.name for io in table.board.hil_inputs}
    sensor = [p for p in rpdos if set(p.names) == inputs]
    stream = table.setpoint_stream
    setpoint = [p for p in rpdos if stream and set(stream) <= set(p.names)]
    cyclic = tuple(p for p in tpdos if p.is_cyclic)
    status = [p for p in cyclic if "fault_flags" in p.names]
    problems = []
    if not sensor:
        problems.append(f"no enabled RPDO maps exactly the HIL inputs {sorted(inputs)}")
    if not setpoint:
        problems.append(f"no enabled RPDO maps the setpoint stream {stream} (fields with stream = true)")
    if not status or set(status[0].names) != {"safe_state", "fault_flags"}:
        problems.append("no synchronous TPDO maps exactly safe_state and fault_flags")
    if problems:
        raise PdoMappingError(f"{eds}: " + "; ".join(problems))

    def default(name: str) -> float:
        return float(od[name].default)

    def encoded(name: str, value: float) -> tuple[int, int, bytes]:
        var = od[name]
        return var.index, var.subindex, var.encode_raw(value)

    encoder_stale = round(default("encoder_stale_cycles"))
    thermistor_stale = round(default("thermistor_stale_cycles"))
    if thermistor_stale <= encoder_stale + MAX_EXTRA_STALE_CYCLES + 2:
        raise PdoMappingError(
            f"{eds}: thermistor_stale_cycles {thermistor_stale} must exceed encoder_stale_cycles "
            f"{encoder_stale} + {MAX_EXTRA_STALE_CYCLES + 2}: the stale-sensor fault withholds all sensors"
        )
    reads = [
        SdoObject("vendor id", 0x1018, 1, od[0x1018][1].encode_raw(od[0x1018][1].default)),
        SdoObject("product code", 0x1018, 2, od[0x1018][2].encode_raw(od[0x1018][2].default)),
        SdoObject("heartbeat time", 0x1017, 0, od[0x1017].encode_raw(od[0x1017].default)),
    ]
    for name in ("encoder_stale_cycles", "watchdog_cycles", "gear_ratio"):
        index, subindex, data = encoded(name, default(name))
        reads.append(SdoObject(name, index, subindex, data))
    used = {NMT_COB_ID, SYNC_COB_ID, TIME_COB_ID}
    used |= {p.cob_id for p in (*compile_pdos(PdoDirection.RPDO, node.rpdo.map).values(), *tpdos)}
    used |= {emcy_cob_id(node_id), sdo_response_cob_id(node_id), sdo_request_cob_id(node_id)}
    used |= {heartbeat_cob_id(node_id), LSS_MASTER_COB_ID}  # LSS: every node listens (CiA 305)
    used |= {int(base) + node_id for base in FunctionCode if FunctionCode.TPDO1 <= base <= FunctionCode.RPDO4}
    return SoakLayout(
        node_id=node_id,
        sensor=sensor[0],
        setpoint=setpoint[0],
        tpdos=cyclic,
        status=status[0],
        encoder_stale_cycles=encoder_stale,
        thermistor_stale_cycles=thermistor_stale,
        stale_about=tuple(od[bit.about].index for bit in STALE_ENCODER_BITS if bit.about),
        fault_clear=encoded("fault_clear", 1.0),
        control_mode=encoded("control_mode", VELOCITY_MODE),
        sdo_reads=tuple(reads),
        defaults={
            name: default(name)
            for name in ("gear_ratio", "encoder_counts_per_rev", "output_encoder_counts_per_rev")
        },
        used_cob_ids=frozenset(used),
    )


# --- What the rig sends ---------------------------------------------------------------------
class SensorPattern:
    """Raw sensor values of firmware cycle k: the joint turning at constant speed.

    The motor encoder advances MOTOR_COUNTS_PER_CYCLE counts per cycle and wraps at 16 bits (the
    firmware unwraps it); the output encoder follows through the gearbox with the EDS's gear
    ratio and counts per revolution, so the spring is never deflected; the thermistor reads the
    ambient temperature and the motor current is zero. The output velocity is the setpoint of
    the velocity loop, so the controllers run near equilibrium for the whole soak.

    It is the plant of the engine's lockstep driver (`hilrig.plants.interface.Plant`): `sense`
    gives the values of firmware cycle `cycle`, which the soak sets before each cycle (SYNCs
    while the node is stopped are no firmware cycles, so the driver's own cycle count would run
    ahead); `apply` and `step` do nothing and `truth` is the joint at the pattern's speeds,
    never advanced (no physics: the soak's history keeps no truth).
    """

    def __init__(self, layout: SoakLayout, period_us: int) -> None:
        gear = layout.defaults["gear_ratio"]
        motor_cpr = layout.defaults["encoder_counts_per_rev"]
        output_cpr = layout.defaults["output_encoder_counts_per_rev"]
        self.output_per_motor = output_cpr / (motor_cpr * gear)
        params = JointParams()
        self.thermistor_adc = thermistor_adc(params.ntc_r25_ohm, params.thermistor_pullup_ohm)
        RawSensors(0, 0, self.thermistor_adc, 0)  # checked once: `raw` builds them unchecked
        dt = period_us / 1e6
        self.motor_velocity_rad_s = MOTOR_COUNTS_PER_CYCLE / motor_cpr * 2 * math.pi / dt
        self.output_velocity_rad_s = self.motor_velocity_rad_s / gear
        unknown = set(layout.sensor.names) - set(RawSensors.__dataclass_fields__)
        if unknown:
            raise PdoMappingError(
                f"{layout.sensor.label} maps {sorted(unknown)}: the soak has no pattern for it"
            )
        self.cycle = 1
        """The firmware cycle whose values `read` gives (1 = the first)."""
        self._state = dataclasses.replace(
            JointPlant(params).state,
            motor_velocity_rad_s=self.motor_velocity_rad_s,
            load_velocity_rad_s=self.output_velocity_rad_s,
        )

    def raw(self, cycle: int) -> RawSensors:
        """The raw sensor values of firmware cycle `cycle`."""
        motor = cycle * MOTOR_COUNTS_PER_CYCLE
        output = round(motor * self.output_per_motor)
        return RawSensors.in_range(motor & ENCODER_MASK, output & ENCODER_MASK, self.thermistor_adc, 0)

    # The engine's Plant.
    sensor_fields = tuple(RawSensors.__dataclass_fields__)
    actuator_fields = (ACTUATOR_FIELD,)
    truth_fields = STATE_FIELDS[1:]

    def sense(self) -> RawSensors:
        return self.raw(self.cycle)

    def truth(self) -> JointState:
        return self._state

    def truth_matrix(self, snapshots: Sequence[JointState]) -> np.ndarray:
        return state_matrix(snapshots)[:, 1:]

    def truth_parameters(self) -> Mapping[str, float]:
        return {}

    def apply(self, outputs: Sequence[Value] | None) -> None:
        pass

    def step(self, dt_s: float) -> None:
        pass
