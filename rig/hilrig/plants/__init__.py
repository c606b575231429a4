"""The plants: the physics a rig puts on a node, no bus in here. The demo joint's plant,
parameters and sensor models (`plant`, `params`, `sensors`, with the C physics `_plant.c`) and a
robot's chain of joints (`chain`).
The plant interface (`interface.Plant`: sensor fields in, actuator fields applied, truth, a
deterministic step) is all the engine, the session and the tracer know of a plant; the joint
implements it as `joint.JointModel` (and `default_plant` makes one), a module of the chain as
`chain.ChainPhysics.models`, an FMU over FMPy as `fmu.FmuPlant` (its map in `fmu_map`). It
imports nothing else of hilrig but its errors; the engine and everything above
it import it.

Typical use, one control cycle of the lockstep driver::

    params = JointParams.fast_thermal()
    plant = JointPlant(params)
    sensors = SensorModel(params, seed=1)
    raw = sensors.read(plant.state)                  # -> RPDO1
    plant.step(1e-3, duty_from_motor_duty(motor_duty))  # motor_duty <- TPDO1

A robot of N such modules (a snake; its links in MuJoCo, needs hilrig[robot]) is
hilrig.plants.chain.ChainPhysics: import it from there, this package does not load MuJoCo.
"""

try:
    from hilrig.plants import _plant  # noqa: F401  (the C physics, compiled by the install)
except ImportError as error:
    raise ImportError(
        "hilrig.plants._plant, the joint's physics in C, is not built: run tools/deps "
        "(or: .venv/bin/python -m pip install --no-build-isolation --no-deps -e rig)"
    ) from error
from hilrig.plants.interface import Plant
from hilrig.plants.params import FAST_THERMAL_TIME_CONSTANT_S, JointParams
from hilrig.plants.plant import (
    MOTOR_DUTY_FULL_SCALE,
    STATE_FIELDS,
    SUBSTEP_FRACTION,
    JointPlant,
    JointState,
    duty_from_motor_duty,
    state_matrix,
)
from hilrig.plants.sensors import (
    CURRENT_COUNTS_PER_A,
    ENCODER_MODULUS,
    THERMISTOR_ADC_MAX,
    EncoderUnwrapper,
    RawSensors,
    SensorModel,
    counts_to_current_a,
    counts_to_rad,
    current_counts,
    encoder_counts,
    ntc_resistance,
    ntc_temperature_c,
    read_sensors,
    round_half_away,
    thermistor_adc,
    thermistor_adc_exact,
    thermistor_adc_to_resistance,
    thermistor_adc_to_temperature_c,
    wrapped_count_delta,
)

__all__ = [
    "CURRENT_COUNTS_PER_A",
    "ENCODER_MODULUS",
    "FAST_THERMAL_TIME_CONSTANT_S",
    "MOTOR_DUTY_FULL_SCALE",
    "STATE_FIELDS",
    "SUBSTEP_FRACTION",
    "THERMISTOR_ADC_MAX",
    "EncoderUnwrapper",
    "JointParams",
    "JointPlant",
    "JointState",
    "Plant",
    "RawSensors",
    "SensorModel",
    "counts_to_current_a",
    "counts_to_rad",
    "current_counts",
    "default_plant",
    "duty_from_motor_duty",
    "encoder_counts",
    "ntc_resistance",
    "ntc_temperature_c",
    "read_sensors",
    "round_half_away",
    "state_matrix",
    "thermistor_adc",
    "thermistor_adc_exact",
    "thermistor_adc_to_resistance",
    "thermistor_adc_to_temperature_c",
    "wrapped_count_delta",
]


def default_plant(params: object | None = None, seed: int = 0) -> Plant:
    """The plant of a rig given none: the demo joint (`hilrig.plants.joint.JointModel`) with
    `params` (a JointParams; None: the defaults) and sensor noise of `seed`."""
    from hilrig.plants.joint import JointModel

    if params is not None and not isinstance(params, JointParams):
        raise TypeError(f"params: expected JointParams for the default plant, got {type(params).__name__}")
    return JointModel.of(params, seed)
