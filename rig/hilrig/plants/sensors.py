"""Sensor models of the demo joint: plant state -> the raw integers the rig sends in RPDO1.

Forward conversions (what the hardware does) and their inverses (what the firmware
does, kept here as a reference so tests can check both sides against each other).
The raw types follow the HIL I/O contract: both encoders are U16 counters that wrap at
65536, the thermistor is a 12-bit ADC of a divider 3.3 V -- pull-up -- node -- NTC --
GND, the current sensor is I16 with 1 count = 1 mA.

Rounding is half away from zero, like C's lround, so that the firmware's C++
conversions and these agree bit for bit on exact inputs.

The per-cycle path (`read_sensors`, `SensorModel.read`) runs the same conversions in C
(hilrig.plants._plant, for the rig's emulated CPU); the functions here are the readable
reference, and the tests hold both to identical readings.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from array import array
from collections.abc import Iterator
from dataclasses import dataclass
from itertools import chain, repeat

import numpy as np

from hilrig.plants import _plant
from hilrig.plants.params import JointParams
from hilrig.plants.plant import JointState

ENCODER_MODULUS = 65536
"""U16 encoder counters wrap here."""
THERMISTOR_ADC_MAX = 4095
"""Full scale of the 12-bit thermistor ADC."""
CURRENT_COUNTS_PER_A = 1000
"""motor_current_adc counts per ampere (1 count = 1 mA)."""
KELVIN_AT_0_C = 273.15
NTC_REFERENCE_TEMPERATURE_K = 298.15
"""The NTC's R25 is specified at 25 degC."""
DEFAULT_PULLUP_OHM = 10_000.0

_U16_RANGE = (0, 65535)
_I16_RANGE = (-32768, 32767)


def round_half_away(value: float) -> int:
    """Round to the nearest integer, halves away from zero (C's lround)."""
    return int(math.copysign(math.floor(abs(value) + 0.5), value))


# --- Encoders -------------------------------------------------------------------------
def encoder_counts(angle_rad: float, counts_per_rev: int) -> int:
    """Raw U16 reading of an incremental encoder at `angle_rad` (0 counts at 0 rad).

    A counter changes at each edge, so the count is the floor of the exact position
    in counts: quantization error is 0..1 count, always behind the true angle.
    """
    return math.floor(angle_rad * counts_per_rev / (2.0 * math.pi)) % ENCODER_MODULUS


def wrapped_count_delta(previous_raw: int, raw: int) -> int:
    """Signed change between two U16 readings, assuming |change| < 32768 counts."""
    half = ENCODER_MODULUS // 2
    return (raw - previous_raw + half) % ENCODER_MODULUS - half


def counts_to_rad(counts: int, counts_per_rev: int) -> float:
    """Angle of a continuous (unwrapped) count [rad]."""
    return counts * 2.0 * math.pi / counts_per_rev


class EncoderUnwrapper:
    """Firmware-side reference: turns successive U16 readings into a continuous count.

    The first reading is taken as signed (65535 -> -1), since the counter starts at 0
    at power-up and a reading just below 65536 means "slightly negative". Readings
    must come often enough that the shaft moves less than half a wrap (32768 counts)
    between them: at 1 kHz that is 8 motor revolutions per cycle.
    """

    def __init__(self) -> None:
        self._previous_raw: int | None = None
        self._counts = 0

    @property
    def counts(self) -> int:
        """Continuous count after the last update (0 before the first)."""
        return self._counts

    def update(self, raw: int) -> int:
        """Take one raw U16 reading; return the continuous count."""
        if not _U16_RANGE[0] <= raw <= _U16_RANGE[1]:
            raise ValueError(f"encoder reading: expected U16 (0..65535), got {raw}")
        if self._previous_raw is None:
            self._counts = wrapped_count_delta(0, raw)
        else:
            self._counts += wrapped_count_delta(self._previous_raw, raw)
        self._previous_raw = raw
        return self._counts


# --- Thermistor -----------------------------------------------------------------------
def ntc_resistance(temperature_c: float, r25_ohm: float, beta_k: float) -> float:
    """NTC resistance at `temperature_c` (beta model) [ohm]."""
    temperature_k = temperature_c + KELVIN_AT_0_C
    return r25_ohm * math.exp(beta_k * (1.0 / temperature_k - 1.0 / NTC_REFERENCE_TEMPERATURE_K))


def ntc_temperature_c(resistance_ohm: float, r25_ohm: float, beta_k: float) -> float:
    """Inverse of `ntc_resistance` [degC]; raises ValueError for a non-positive resistance."""
    if not (resistance_ohm > 0.0 and math.isfinite(resistance_ohm)):
        raise ValueError(f"NTC resistance: expected finite > 0 ohm, got {resistance_ohm}")
    inverse_k = 1.0 / NTC_REFERENCE_TEMPERATURE_K + math.log(resistance_ohm / r25_ohm) / beta_k
    return 1.0 / inverse_k - KELVIN_AT_0_C


def thermistor_adc_exact(ntc_ohm: float, pullup_ohm: float = DEFAULT_PULLUP_OHM) -> float:
    """Unrounded ADC value of the divider, 4095 * R_ntc / (R_ntc + R_pullup) [counts]."""
    return THERMISTOR_ADC_MAX * ntc_ohm / (ntc_ohm + pullup_ohm)


def thermistor_adc(ntc_ohm: float, pullup_ohm: float = DEFAULT_PULLUP_OHM) -> int:
    """12-bit ADC reading of the divider, round(4095 * R_ntc / (R_ntc + R_pullup))."""
    return round_half_away(thermistor_adc_exact(ntc_ohm, pullup_ohm))


def thermistor_adc_to_resistance(adc: int, pullup_ohm: float = DEFAULT_PULLUP_OHM) -> float:
    """Inverse of `thermistor_adc` [ohm].

    0 (shorted NTC) and 4095 (open NTC) have no finite resistance; they and values a
    12-bit ADC cannot produce raise ValueError: a sensor fault, not a temperature.
    """
    if not 1 <= adc <= THERMISTOR_ADC_MAX - 1:
        raise ValueError(
            f"thermistor_adc: expected 1..{THERMISTOR_ADC_MAX - 1} "
            f"(0 = shorted, {THERMISTOR_ADC_MAX} = open NTC), got {adc}"
        )
    return pullup_ohm * adc / (THERMISTOR_ADC_MAX - adc)


def thermistor_adc_to_temperature_c(adc: int, params: JointParams) -> float:
    """Winding temperature the firmware derives from a thermistor reading [degC]."""
    resistance = thermistor_adc_to_resistance(adc, params.thermistor_pullup_ohm)
    return ntc_temperature_c(resistance, params.ntc_r25_ohm, params.ntc_beta_k)


# --- Current sensor -------------------------------------------------------------------
def current_counts(current_a: float) -> int:
    """motor_current_adc for `current_a`: 1 count = 1 mA, saturating at the I16 range."""
    counts = round_half_away(current_a * CURRENT_COUNTS_PER_A)
    return min(_I16_RANGE[1], max(_I16_RANGE[0], counts))


def counts_to_current_a(counts: int) -> float:
    """Inverse of `current_counts` [A]."""
    return counts / CURRENT_COUNTS_PER_A


# --- Raw sensor frame -----------------------------------------------------------------
_WIRE_RANGES = {
    "motor_encoder_counts": _U16_RANGE,
    "output_encoder_counts": _U16_RANGE,
    "thermistor_adc": _U16_RANGE,
    "motor_current_adc": _I16_RANGE,
}


@dataclass(frozen=True, slots=True)
class RawSensors:
    """The raw sensor values the rig sends in RPDO1, named as the HIL inputs in board.toml.

    Values are checked against their wire type only (U16 / I16), so faults a real
    sensor could not produce, such as thermistor_adc = 5000, can still be injected:
    override any value with `dataclasses.replace(raw, thermistor_adc=4095)`.
    """

    motor_encoder_counts: int
    """U16 motor-side encoder counter, wraps at 65536."""
    output_encoder_counts: int
    """U16 load-side encoder counter, wraps at 65536."""
    thermistor_adc: int
    """U16 carrying the 12-bit thermistor ADC reading (0..4095 from real hardware)."""
    motor_current_adc: int
    """I16 winding current, 1 count = 1 mA."""

    def __post_init__(self) -> None:
        for name, (low, high) in _WIRE_RANGES.items():
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int):
                raise TypeError(f"RawSensors.{name}: expected int, got {type(value).__name__}")
            if not low <= value <= high:
                raise ValueError(f"RawSensors.{name}: expected {low}..{high}, got {value}")

    @classmethod
    def in_range(
        cls,
        motor_encoder_counts: int,
        output_encoder_counts: int,
        thermistor_adc: int,
        motor_current_adc: int,
    ) -> RawSensors:
        """Values that are in their wire ranges by construction (wrapped counters, a fixed ADC
        reading), built without the check, as the physics builds its readings in C: for a
        source of a reading every cycle, where the check would be a cost of every cycle."""
        raw = object.__new__(cls)
        _set(raw, "motor_encoder_counts", motor_encoder_counts)
        _set(raw, "output_encoder_counts", output_encoder_counts)
        _set(raw, "thermistor_adc", thermistor_adc)
        _set(raw, "motor_current_adc", motor_current_adc)
        return raw

    def as_dict(self) -> dict[str, int]:
        """Values by HIL input name, for writing into the RPDO's mapped variables."""
        return dataclasses.asdict(self)


_set = object.__setattr__  # what a frozen dataclass's own __init__ uses


def sensor_coefficients(params: JointParams) -> dict[str, float]:
    """The constants _plant.c's raw_sensors reads by name, in the order of _joint_core.h's S_*
    enum (all floats); the joint's FMU takes those without noise as its parameters."""
    p = params
    coefficients = {
        name: float(value)
        for name, value in (
            ("motor_encoder_counts_per_rev", p.motor_encoder_counts_per_rev),
            ("output_encoder_counts_per_rev", p.output_encoder_counts_per_rev),
            ("ntc_r25_ohm", p.ntc_r25_ohm),
            ("ntc_beta_k", p.ntc_beta_k),
            ("thermistor_pullup_ohm", p.thermistor_pullup_ohm),
            (NOISE_COEFFICIENTS[0], p.thermistor_adc_noise_counts),
            (NOISE_COEFFICIENTS[1], p.current_sensor_noise_a),
        )
    }
    assert len(coefficients) == _plant.SENSOR_COEFFICIENT_COUNT
    return coefficients


NOISE_COEFFICIENTS = ("thermistor_adc_noise_counts", "current_sensor_noise_a")
"""The sensor coefficients that scale the noise (the last of the S_* enum): the joint's FMU has no
noise of its own (a plant map adds it)."""


@functools.lru_cache(maxsize=64)
def _sensor_coefficients(params: JointParams) -> bytes:
    """`sensor_coefficients` packed as _plant.c takes them (native doubles; kept per params:
    `read_sensors` asks every read)."""
    return array("d", sensor_coefficients(params).values()).tobytes()


def read_sensors(state: JointState, params: JointParams, rng: np.random.Generator) -> RawSensors:
    """Raw sensor values for `state`, with seeded Gaussian noise on the two ADCs.

    Encoders carry no noise: their error is quantization. Exactly two normal
    variates are drawn per call whatever the noise levels, so the random stream (and
    with it every later reading) does not depend on which noise is switched on.
    Same as: encoder_counts of both angles, thermistor_adc of the NTC plus noise (clamped
    to 0..4095), current_counts of the current plus noise.
    """
    thermistor_noise, current_noise = rng.standard_normal(2)
    return _plant.raw_sensors(
        RawSensors, _sensor_coefficients(params), state, float(thermistor_noise), float(current_noise)
    )


NOISE_BLOCK_READS = 512
"""Reads whose noise a SensorModel with its own generator draws in one numpy call."""


class SensorModel:
    """The joint's sensors with their own seeded noise stream.

    seed: an int (same seed, same noise, run after run) or a numpy Generator to share.
    With an int seed the normals are drawn NOISE_BLOCK_READS reads at a time (a numpy call
    costs more than the reading itself); Generator.standard_normal yields the same sequence
    in blocks as two at a time, so every reading equals `read_sensors` with that generator.
    A shared Generator is drawn from two normals per read, never ahead of the other users.
    """

    def __init__(self, params: JointParams, seed: int | np.random.Generator) -> None:
        self._params = params
        self.packed_coefficients = _sensor_coefficients(params)
        """The sensor models' coefficients as `_plant.raw_sensors` takes them."""
        rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        self._rng = rng
        block = 2 if isinstance(seed, np.random.Generator) else 2 * NOISE_BLOCK_READS
        self.normals: Iterator[float] = chain.from_iterable(
            map(lambda _: rng.standard_normal(block).tolist(), repeat(None))
        )
        """The noise stream, two normals a read: an iterator of C parts, which `_plant.raw_sensors`
        draws from itself (a block drawn only when the last one is used up)."""

    def read(self, state: JointState) -> RawSensors:
        """Raw values for `state`; each call draws fresh noise."""
        return _plant.raw_sensors(RawSensors, self.packed_coefficients, state, self.normals)
