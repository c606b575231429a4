/* The demo joint's physics in C: RK4 integration of the plant and the sensor conversions of
 * one control cycle. hilrig.plants.plant and .sensors are the Python API around it.
 *
 * Why C: the lockstep rig runs in a qemu micro-VM with software CPU emulation, where Python's
 * float code is what the emulation is slowest at: in Python, one RK4 step would take longer
 * than the control cycle it stands for.
 *
 * Bit-identity: these are the same floating-point operations in the same order as the
 * original Python (rig/tests/data/physics_reference.json was recorded from it and
 * test_physics_reference.py asserts equality of every bit). That needs: no contraction into
 * FMA (-ffp-contract=off), no -ffast-math, and libm's tanh/exp, which Python's math module
 * calls too. `a + b * c` in Python is a + (b * c); each expression below keeps Python's
 * left-to-right grouping.
 *
 * --- The plant ------------------------------------------------------------------------------
 * DC motor, gearbox, series-elastic spring, load, winding heat. State (6 values): motor angle
 * and speed, load angle and speed, winding current, winding temperature.
 *
 * Integrator: classic RK4 with fixed sub-steps inside each step. The sub-step is
 * SUBSTEP_FRACTION of the plant's fastest time scale, taken from the electrical time constant
 * L/R (at the present winding temperature, since R rises when hot), the spring's natural
 * frequency with a free rotor, the electromechanical resonance sqrt(kt ke / (L J)), the
 * mechanical damping rates and the slope of the smoothed Coulomb friction (all but L/R are
 * computed once, in plant.py). With h*lambda <= 0.5 RK4 is far inside its stability region
 * (|lambda h| < 2.78 on the real axis) and its per-step error is ~1e-4 of the fastest
 * decaying mode, so a 1 ms control period on the default joint takes 4 sub-steps
 * (L/R = 0.5 ms). A semi-implicit Euler would be cheaper but only first-order accurate, and
 * the tests compare against closed forms tightly.
 *
 * H-bridge convention: the winding sees duty * bus voltage. Duty 0 shorts the winding
 * (complementary PWM, both low sides on), so a spinning motor brakes through its back-EMF.
 *
 * Python objects: the state lives in JointState instances (frozen slotted dataclasses); a step
 * reads the previous one and builds the next one of the same type, so the plant's state is
 * plain data. Constants come as packed doubles (bytes) built once from JointParams (order: the
 * enums of _joint_core.h, mirrored in plant.py / sensors.py). The physics and the sensors'
 * arithmetic are _joint_core.h's, shared with the joint's FMU (_joint_fmu.c); this file is
 * their Python face: argument checks, Python's errors, JointState and RawSensors objects.
 */
#define PY_SSIZE_T_CLEAN
#define Py_LIMITED_API 0x030B0000 /* the stable ABI of CPython 3.11+: one wheel for them all (abi3) */
#include <Python.h>
#include <string.h>

#include "_joint_core.h"

/* JointState's fields in declaration order; the first 7 are the time and the state. */
enum {
    F_TIME,
    F_MOTOR_ANGLE,
    F_MOTOR_VELOCITY,
    F_LOAD_ANGLE,
    F_LOAD_VELOCITY,
    F_CURRENT,
    F_TEMPERATURE,
    F_SPRING_DEFLECTION,
    F_SPRING_TORQUE,
    F_RESISTANCE,
    F_APPLIED_DUTY,
    F_COUNT
};
static const char *const joint_state_field_names[F_COUNT] = {
    "time_s",
    "motor_angle_rad",
    "motor_velocity_rad_s",
    "load_angle_rad",
    "load_velocity_rad_s",
    "current_a",
    "winding_temperature_c",
    "spring_deflection_rad",
    "spring_torque_nm",
    "winding_resistance_ohm",
    "applied_duty",
};

enum { R_MOTOR_ENCODER, R_OUTPUT_ENCODER, R_THERMISTOR, R_CURRENT, R_COUNT };
static const char *const raw_sensor_field_names[R_COUNT] = {
    "motor_encoder_counts",
    "output_encoder_counts",
    "thermistor_adc",
    "motor_current_adc",
};

typedef struct {
    PyObject *joint_state_names[F_COUNT];
    PyObject *raw_sensor_names[R_COUNT];
} module_state;

static module_state *get_state(PyObject *module) { return (module_state *)PyModule_GetState(module); }

/* --- Argument helpers ------------------------------------------------------------------ */
/* Coefficients come packed, as the native doubles they are here (bytes of `count` doubles, made
 * once per plant by plant.py/sensors.py): a copy, not `count` float objects unboxed per call. */
static int read_coefficients(PyObject *packed, double *out, Py_ssize_t count, const char *what)
{
    if (!PyBytes_CheckExact(packed) || PyBytes_Size(packed) != count * (Py_ssize_t)sizeof(double)) {
        PyErr_Format(PyExc_TypeError, "%s: expected bytes of %zd doubles, got %R", what, count, packed);
        return -1;
    }
    memcpy(out, PyBytes_AsString(packed), (size_t)count * sizeof(double));
    return 0;
}

static int read_double(PyObject *object, double *out)
{
    double value = PyFloat_AsDouble(object);
    if (value == -1.0 && PyErr_Occurred()) return -1;
    *out = value;
    return 0;
}

/* Reads fields [0, count) of a JointState into `out`. */
static int read_fields(PyObject *object, PyObject *const *names, int count, double *out)
{
    for (int i = 0; i < count; i++) {
        PyObject *value = PyObject_GetAttr(object, names[i]);
        if (value == NULL) return -1;
        int failed = read_double(value, &out[i]);
        Py_DECREF(value);
        if (failed) return -1;
    }
    return 0;
}

/* A new instance of a frozen slotted dataclass, fields set without __init__/__post_init__:
 * only for values this module computed (users' instances still go through validation). */
static PyObject *new_frozen(PyTypeObject *type, PyObject *const *names, PyObject **values, int count)
{
    allocfunc alloc = (allocfunc)PyType_GetSlot(type, Py_tp_alloc);
    PyObject *object = alloc != NULL ? alloc(type, 0) : NULL;
    for (int i = 0; i < count; i++) {
        if (object != NULL && values[i] != NULL && PyObject_GenericSetAttr(object, names[i], values[i]) < 0) {
            Py_CLEAR(object);
        }
        if (values[i] == NULL && object != NULL) Py_CLEAR(object); /* a value failed to build */
    }
    for (int i = 0; i < count; i++) Py_XDECREF(values[i]);
    return object;
}

/* A JointState of `type` for time, state and duty, with the derived quantities. */
static PyObject *build_joint_state(module_state *st, PyTypeObject *type, const double *c, double time_s,
                                   const double *x, double applied_duty)
{
    double deflection, spring_torque;
    joint_spring(c, x, &deflection, &spring_torque);
    double fields[F_COUNT] = {
        [F_TIME] = time_s,
        [F_MOTOR_ANGLE] = x[X_MOTOR_ANGLE],
        [F_MOTOR_VELOCITY] = x[X_MOTOR_VELOCITY],
        [F_LOAD_ANGLE] = x[X_LOAD_ANGLE],
        [F_LOAD_VELOCITY] = x[X_LOAD_VELOCITY],
        [F_CURRENT] = x[X_CURRENT],
        [F_TEMPERATURE] = x[X_TEMPERATURE],
        [F_SPRING_DEFLECTION] = deflection,
        [F_SPRING_TORQUE] = spring_torque,
        [F_RESISTANCE] = winding_resistance(c, x[X_TEMPERATURE]),
        [F_APPLIED_DUTY] = applied_duty,
    };
    PyObject *values[F_COUNT];
    for (int i = 0; i < F_COUNT; i++) values[i] = PyFloat_FromDouble(fields[i]);
    return new_frozen(type, st->joint_state_names, values, F_COUNT);
}

/* advance(coefficients, state, dt_s, duty, load_torque_nm, motor_held, ambient_c) -> JointState
 *
 * The next JointState (same type as `state`) after `dt_s` with `duty` held constant. Validates
 * dt_s, duty and load torque like JointPlant.step documents; clamps duty to [-1, 1]. */
static PyObject *advance(PyObject *module, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 7) {
        PyErr_Format(PyExc_TypeError, "advance: expected 7 arguments, got %zd", nargs);
        return NULL;
    }
    module_state *st = get_state(module);
    double c[PLANT_COEFFICIENT_COUNT];
    double now[1 + X_COUNT];
    double dt_s, duty, load_torque, ambient;
    if (read_coefficients(args[0], c, PLANT_COEFFICIENT_COUNT, "plant coefficients") < 0) return NULL;
    if (read_fields(args[1], st->joint_state_names, 1 + X_COUNT, now) < 0) return NULL;
    if (read_double(args[2], &dt_s) < 0 || read_double(args[3], &duty) < 0
        || read_double(args[4], &load_torque) < 0 || read_double(args[6], &ambient) < 0) {
        return NULL;
    }
    int motor_held = PyObject_IsTrue(args[5]);
    if (motor_held < 0) return NULL;
    if (!(isfinite(dt_s) && dt_s > 0.0)) {
        PyErr_Format(PyExc_ValueError, "dt_s: expected finite > 0, got %S", args[2]);
        return NULL;
    }
    if (!isfinite(duty)) {
        PyErr_Format(PyExc_ValueError, "duty: expected a finite number in [-1, 1], got %S", args[3]);
        return NULL;
    }
    if (!isfinite(load_torque)) {
        PyErr_Format(PyExc_ValueError, "load_torque_nm: expected finite, got %S", args[4]);
        return NULL;
    }
    /* An H-bridge cannot exceed its supply. */
    if (duty > 1.0) duty = 1.0;
    if (duty < -1.0) duty = -1.0;
    double voltage = duty * c[C_BUS_VOLTAGE];

    double *x = &now[1];
    if (joint_advance(c, x, dt_s, voltage, load_torque, motor_held, ambient) < 0) {
        PyErr_Format(PyExc_ValueError, "dt_s: %S needs more than 1e9 RK4 sub-steps", args[2]);
        return NULL;
    }
    for (int i = 0; i < X_COUNT; i++) {
        if (!isfinite(x[i])) {
            /* Only reachable with parameters far outside a joint's range; fail loudly instead
             * of handing NaN encoder counts to the firmware. */
            char *at = PyOS_double_to_string(now[0], 'f', 6, 0, NULL);
            PyObject *values = Py_BuildValue("(dddddd)", x[0], x[1], x[2], x[3], x[4], x[5]);
            if (at != NULL && values != NULL) {
                PyErr_Format(PyExc_FloatingPointError, "plant state diverged at t = %s s: %R", at, values);
            }
            PyMem_Free(at);
            Py_XDECREF(values);
            return NULL;
        }
    }
    return build_joint_state(st, Py_TYPE(args[1]), c, now[0] + dt_s, x, duty);
}

/* joint_state(JointState, coefficients, time_s, motor_angle, motor_velocity, load_angle,
 *             load_velocity, current, temperature, applied_duty) -> JointState */
static PyObject *joint_state(PyObject *module, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 10 || !PyType_Check(args[0])) {
        PyErr_SetString(PyExc_TypeError, "joint_state: expected (type, coefficients, 8 floats)");
        return NULL;
    }
    double c[PLANT_COEFFICIENT_COUNT];
    double values[8];
    if (read_coefficients(args[1], c, PLANT_COEFFICIENT_COUNT, "plant coefficients") < 0) return NULL;
    for (int i = 0; i < 8; i++) {
        if (read_double(args[2 + i], &values[i]) < 0) return NULL;
    }
    return build_joint_state(get_state(module), (PyTypeObject *)args[0], c, values[0], &values[1], values[7]);
}

/* max_substep_s(coefficients, temperature_c) -> float */
static PyObject *max_substep_s(PyObject *module, PyObject *const *args, Py_ssize_t nargs)
{
    (void)module;
    double c[PLANT_COEFFICIENT_COUNT];
    double temperature;
    if (nargs != 2) {
        PyErr_SetString(PyExc_TypeError, "max_substep_s: expected (coefficients, temperature_c)");
        return NULL;
    }
    if (read_coefficients(args[0], c, PLANT_COEFFICIENT_COUNT, "plant coefficients") < 0) return NULL;
    if (read_double(args[1], &temperature) < 0) return NULL;
    return PyFloat_FromDouble(max_substep(c, temperature));
}

/* --- Sensors ---------------------------------------------------------------------------- */
/* Python's int(value) errors, for values a float cannot hand to an integer counter. */
static int check_integral(double value)
{
    if (isnan(value)) {
        PyErr_SetString(PyExc_ValueError, "cannot convert float NaN to integer");
        return -1;
    }
    if (isinf(value)) {
        PyErr_SetString(PyExc_OverflowError, "cannot convert float infinity to integer");
        return -1;
    }
    return 0;
}

/* sensors.round_half_away (C's lround), then saturated to [low, high]. */
static PyObject *rounded_saturated(double value, double low, double high)
{
    if (check_integral(value) < 0) return NULL;
    return PyLong_FromDouble(joint_round_saturated(value, low, high));
}

/* sensors.encoder_counts: floor of the position in counts, wrapped to U16. */
static PyObject *encoder_counts(double angle_rad, double counts_per_rev)
{
    double counts = joint_encoder_position(angle_rad, counts_per_rev);
    if (check_integral(counts) < 0) return NULL;
    return PyLong_FromDouble(joint_wrapped_counts(counts));
}

/* sensors.ntc_resistance and thermistor_adc_exact: unrounded ADC counts at a temperature. */
static int thermistor_adc_exact(const double *s, double temperature_c, double *adc)
{
    double temperature_k = temperature_c + KELVIN_AT_0_C;
    if (temperature_k == 0.0) {
        PyErr_SetString(PyExc_ZeroDivisionError, "float division by zero");
        return -1;
    }
    double exponent = joint_ntc_exponent(s, temperature_k);
    double growth = exp(exponent);
    if (isinf(growth) && isfinite(exponent)) {
        PyErr_SetString(PyExc_OverflowError, "math range error");
        return -1;
    }
    *adc = joint_thermistor_adc(s, growth);
    return 0;
}

/* The next value of the iterator `normals` as a double (-1 with an error set when it ends). */
static int next_normal(PyObject *normals, double *out)
{
    PyObject *value = PyIter_Next(normals);
    if (value == NULL) {
        if (!PyErr_Occurred()) PyErr_SetString(PyExc_ValueError, "raw_sensors: the normals ran out");
        return -1;
    }
    int failed = read_double(value, out);
    Py_DECREF(value);
    return failed;
}

/* raw_sensors(RawSensors, coefficients, state, thermistor_noise, current_noise) -> RawSensors
 * raw_sensors(RawSensors, coefficients, state, normals) -> RawSensors
 *
 * sensors.read_sensors after its noise draw: encoders floor and wrap, the thermistor divider
 * and the current sensor round half away from zero and saturate at their ranges. The noises are
 * two floats, or the next two of the iterator `normals` (a SensorModel's stream: no Python call
 * in between, every cycle). */
static PyObject *raw_sensors(PyObject *module, PyObject *const *args, Py_ssize_t nargs)
{
    if ((nargs != 5 && nargs != 4) || !PyType_Check(args[0]) || (nargs == 4 && !PyIter_Check(args[3]))) {
        PyErr_SetString(PyExc_TypeError, "raw_sensors: expected (type, coefficients, state, thermistor_noise, "
                                         "current_noise) or (type, coefficients, state, normals)");
        return NULL;
    }
    module_state *st = get_state(module);
    double s[SENSOR_COEFFICIENT_COUNT];
    double state[1 + X_COUNT];
    double thermistor_noise, current_noise, adc;
    if (read_coefficients(args[1], s, SENSOR_COEFFICIENT_COUNT, "sensor coefficients") < 0) return NULL;
    if (read_fields(args[2], st->joint_state_names, 1 + X_COUNT, state) < 0) return NULL;
    if (nargs == 4 ? next_normal(args[3], &thermistor_noise) < 0 || next_normal(args[3], &current_noise) < 0
                   : read_double(args[3], &thermistor_noise) < 0 || read_double(args[4], &current_noise) < 0) {
        return NULL;
    }
    const double *x = &state[1];

    if (thermistor_adc_exact(s, x[X_TEMPERATURE], &adc) < 0) return NULL;
    adc += s[S_THERMISTOR_NOISE_COUNTS] * thermistor_noise;
    double current = x[X_CURRENT] + s[S_CURRENT_NOISE_A] * current_noise;

    PyObject *values[R_COUNT];
    values[R_MOTOR_ENCODER] = encoder_counts(x[X_MOTOR_ANGLE], s[S_MOTOR_COUNTS_PER_REV]);
    values[R_OUTPUT_ENCODER] = values[R_MOTOR_ENCODER] == NULL
                                   ? NULL
                                   : encoder_counts(x[X_LOAD_ANGLE], s[S_OUTPUT_COUNTS_PER_REV]);
    values[R_THERMISTOR] = values[R_OUTPUT_ENCODER] == NULL ? NULL
                                                            : rounded_saturated(adc, 0.0, THERMISTOR_ADC_MAX);
    values[R_CURRENT] = values[R_THERMISTOR] == NULL
                            ? NULL
                            : rounded_saturated(current * CURRENT_COUNTS_PER_A, I16_MIN, I16_MAX);
    return new_frozen((PyTypeObject *)args[0], st->raw_sensor_names, values, R_COUNT);
}

/* --- Reading states back --------------------------------------------------------------- */
/* state_values(states) -> bytes
 *
 * Every field of each JointState in `states` (a list or tuple), in declaration order, as
 * native float64s, row after row: what the tracer turns into the truth's columns (numpy reads
 * it without a copy). Python's own loop over the attributes cost ~550 instructions a value. */
static PyObject *state_values(PyObject *module, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 1) {
        PyErr_SetString(PyExc_TypeError, "state_values: expected (states)");
        return NULL;
    }
    PyObject *states = args[0];
    int is_list = PyList_Check(states);
    if (!is_list && !PyTuple_Check(states)) {
        PyErr_SetString(PyExc_TypeError, "state_values: expected a list or tuple of JointState");
        return NULL;
    }
    Py_ssize_t count = is_list ? PyList_Size(states) : PyTuple_Size(states);
    PyObject *bytes = PyBytes_FromStringAndSize(NULL, count * F_COUNT * (Py_ssize_t)sizeof(double));
    if (bytes != NULL) {
        double *out = (double *)PyBytes_AsString(bytes);
        module_state *st = get_state(module);
        for (Py_ssize_t i = 0; i < count; i++) {
            PyObject *item = is_list ? PyList_GetItem(states, i) : PyTuple_GetItem(states, i); /* borrowed */
            if (item == NULL || read_fields(item, st->joint_state_names, F_COUNT, &out[i * F_COUNT]) < 0) {
                Py_CLEAR(bytes);
                break;
            }
        }
    }
    return bytes;
}

/* --- Module ----------------------------------------------------------------------------- */
static PyMethodDef methods[] = {
    {"advance", (PyCFunction)(void (*)(void))advance, METH_FASTCALL,
     "advance(coefficients, state, dt_s, duty, load_torque_nm, motor_held, ambient_c) -> JointState"},
    {"joint_state", (PyCFunction)(void (*)(void))joint_state, METH_FASTCALL,
     "joint_state(JointState, coefficients, time_s, motor_angle, motor_velocity, load_angle, "
     "load_velocity, current, temperature, applied_duty) -> JointState"},
    {"max_substep_s", (PyCFunction)(void (*)(void))max_substep_s, METH_FASTCALL,
     "max_substep_s(coefficients, temperature_c) -> float"},
    {"state_values", (PyCFunction)(void (*)(void))state_values, METH_FASTCALL,
     "state_values(states) -> bytes: every field of each JointState, in order, as float64s"},
    {"raw_sensors", (PyCFunction)(void (*)(void))raw_sensors, METH_FASTCALL,
     "raw_sensors(RawSensors, coefficients, state, thermistor_noise, current_noise) -> RawSensors\n"
     "raw_sensors(RawSensors, coefficients, state, normals) -> RawSensors (two of the iterator's)"},
    {NULL, NULL, 0, NULL},
};

static int module_exec(PyObject *module)
{
    module_state *st = get_state(module);
    for (int i = 0; i < F_COUNT; i++) {
        st->joint_state_names[i] = PyUnicode_InternFromString(joint_state_field_names[i]);
        if (st->joint_state_names[i] == NULL) return -1;
    }
    for (int i = 0; i < R_COUNT; i++) {
        st->raw_sensor_names[i] = PyUnicode_InternFromString(raw_sensor_field_names[i]);
        if (st->raw_sensor_names[i] == NULL) return -1;
    }
    return PyModule_AddIntConstant(module, "PLANT_COEFFICIENT_COUNT", PLANT_COEFFICIENT_COUNT) < 0
               ? -1
               : PyModule_AddIntConstant(module, "SENSOR_COEFFICIENT_COUNT", SENSOR_COEFFICIENT_COUNT);
}

static int module_clear(PyObject *module)
{
    module_state *st = get_state(module);
    for (int i = 0; i < F_COUNT; i++) Py_CLEAR(st->joint_state_names[i]);
    for (int i = 0; i < R_COUNT; i++) Py_CLEAR(st->raw_sensor_names[i]);
    return 0;
}

static void module_free(void *module) { module_clear((PyObject *)module); }

static PyModuleDef_Slot slots[] = {
    {Py_mod_exec, module_exec},
    {0, NULL},
};

static struct PyModuleDef module_def = {
    PyModuleDef_HEAD_INIT,
    .m_name = "hilrig.plants._plant",
    .m_doc = "The demo joint's RK4 plant integration and sensor conversions (see _plant.c).",
    .m_size = sizeof(module_state),
    .m_methods = methods,
    .m_slots = slots,
    .m_clear = module_clear,
    .m_free = module_free,
};

PyMODINIT_FUNC PyInit__plant(void) { return PyModuleDef_Init(&module_def); }
