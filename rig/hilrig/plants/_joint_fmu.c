/* The demo joint as an FMI 2.0 co-simulation FMU: the plant and the sensors of
 * hilrig.plants.joint, on _joint_core.h's arithmetic (the rig's own joint runs the same code
 * through _plant.c), so that other tools can run the joint's model and the rig can run it as an
 * FMU plant with the same trace.
 *
 * tools/joint_fmu.py builds it: it generates joint_fmu_variables.h (the value references, the
 * parameters' start values, the GUID) and modelDescription.xml from the Python side's names
 * (plant.plant_coefficients, sensors.sensor_coefficients), compiles this file against the FMI
 * 2.0 headers FMPy ships, and zips the FMU.
 *
 * Variables: the plant's and the sensors' coefficients as parameters (the noise's excepted:
 * the FMU has none, a plant map adds it), the ambient temperature; one input, the firmware's
 * motor_duty in its wire counts (10000 = full duty); outputs: the four raw sensor readings as
 * the rig sends them (integral values) and the joint's state, as hilrig's JointState names it.
 * doStep advances the state by the communication step with the duty held, as
 * JointPlant.step. The state is a plain struct: getFMUstate / setFMUstate copy it, so a
 * scenario can branch.
 */
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

#include "_joint_core.h"
#include "joint_fmu_variables.h"

typedef struct {
    double v[VR_COUNT]; /* every variable by value reference */
    double x[X_COUNT];  /* the integrator's state */
    double time_s;
} JointValues;

typedef struct {
    JointValues now;
    fmi2CallbackFunctions callbacks;
    char name[128]; /* a copy: the importer's string may not outlive fmi2Instantiate */
    int initialized;
} Joint;

static void say(Joint *joint, fmi2Status status, const char *message)
{
    if (joint->callbacks.logger != NULL) {
        joint->callbacks.logger(joint->callbacks.componentEnvironment, joint->name, status, "logError", "%s",
                                message);
    }
}

static void start_values(JointValues *values)
{
    memset(values, 0, sizeof *values);
    for (int i = 0; i < VR_PARAMETER_COUNT; i++) values->v[i] = joint_fmu_start[i];
}

/* The outputs of the present state: the readings (sensors.py's conversions, noise 0) and the
 * state's quantities. */
static int update_outputs(JointValues *values, double applied_duty)
{
    double *v = values->v;
    const double *c = &v[VR_PLANT];
    double s[SENSOR_COEFFICIENT_COUNT] = {0.0};
    for (int i = 0; i < VR_SENSOR_PARAMETERS; i++) s[i] = v[VR_SENSOR + i];
    const double *x = values->x;
    double temperature_k = x[X_TEMPERATURE] + KELVIN_AT_0_C;
    if (temperature_k == 0.0) return -1;
    double growth = exp(joint_ntc_exponent(s, temperature_k));
    double motor = joint_encoder_position(x[X_MOTOR_ANGLE], s[S_MOTOR_COUNTS_PER_REV]);
    double output = joint_encoder_position(x[X_LOAD_ANGLE], s[S_OUTPUT_COUNTS_PER_REV]);
    if (!isfinite(growth) || !isfinite(motor) || !isfinite(output)) return -1;
    v[VR_MOTOR_ENCODER_COUNTS] = joint_wrapped_counts(motor);
    v[VR_OUTPUT_ENCODER_COUNTS] = joint_wrapped_counts(output);
    v[VR_THERMISTOR_ADC] = joint_round_saturated(joint_thermistor_adc(s, growth), 0.0, THERMISTOR_ADC_MAX);
    v[VR_MOTOR_CURRENT_ADC] = joint_round_saturated(x[X_CURRENT] * CURRENT_COUNTS_PER_A, I16_MIN, I16_MAX);
    double deflection, torque;
    joint_spring(c, x, &deflection, &torque);
    for (int i = 0; i < X_COUNT; i++) v[VR_STATE + i] = x[i];
    v[VR_SPRING_DEFLECTION_RAD] = deflection;
    v[VR_SPRING_TORQUE_NM] = torque;
    v[VR_WINDING_RESISTANCE_OHM] = winding_resistance(c, x[X_TEMPERATURE]);
    v[VR_APPLIED_DUTY] = applied_duty;
    return 0;
}

/* --- Common functions --------------------------------------------------------------------- */
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String categories[])
{
    (void)c, (void)on, (void)n, (void)categories;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String location,
                              const fmi2CallbackFunctions *callbacks, fmi2Boolean visible, fmi2Boolean logging)
{
    (void)location, (void)visible, (void)logging;
    if (type != fmi2CoSimulation || guid == NULL || strcmp(guid, JOINT_FMU_GUID) != 0) return NULL;
    Joint *joint = calloc(1, sizeof *joint);
    if (joint == NULL) return NULL;
    if (callbacks != NULL) joint->callbacks = *callbacks;
    if (name != NULL) strncpy(joint->name, name, sizeof joint->name - 1);
    start_values(&joint->now);
    return joint;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolerance_defined, fmi2Real tolerance,
                               fmi2Real start, fmi2Boolean stop_defined, fmi2Real stop)
{
    (void)tolerance_defined, (void)tolerance, (void)stop_defined, (void)stop;
    ((Joint *)c)->now.time_s = start;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    (void)c;
    return fmi2OK;
}

/* At rest at angle 0, the winding at the ambient temperature (JointPlant's start). */
fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    Joint *joint = c;
    JointValues *now = &joint->now;
    memset(now->x, 0, sizeof now->x);
    now->x[X_TEMPERATURE] = now->v[VR_AMBIENT];
    if (update_outputs(now, 0.0) < 0) {
        say(joint, fmi2Error, "the parameters give no finite sensor readings");
        return fmi2Error;
    }
    joint->initialized = 1;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c)
{
    (void)c;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c)
{
    Joint *joint = c;
    start_values(&joint->now);
    joint->initialized = 0;
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[])
{
    Joint *joint = c;
    for (size_t i = 0; i < n; i++) {
        if (vr[i] >= VR_COUNT) return fmi2Error;
        value[i] = joint->now.v[vr[i]];
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[])
{
    Joint *joint = c;
    for (size_t i = 0; i < n; i++) {
        /* Parameters before initialisation; the duty at any time; outputs never. */
        int parameter = vr[i] < VR_PARAMETER_COUNT;
        if (!(vr[i] == VR_MOTOR_DUTY || (parameter && !joint->initialized))) {
            say(joint, fmi2Error, "only motor_duty may be set after initialisation, outputs never");
            return fmi2Error;
        }
        joint->now.v[vr[i]] = value[i];
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer value[])
{
    (void)c, (void)vr, (void)value;
    return n == 0 ? fmi2OK : fmi2Error;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer value[])
{
    (void)c, (void)vr, (void)value;
    return n == 0 ? fmi2OK : fmi2Error;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean value[])
{
    (void)c, (void)vr, (void)value;
    return n == 0 ? fmi2OK : fmi2Error;
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean value[])
{
    (void)c, (void)vr, (void)value;
    return n == 0 ? fmi2OK : fmi2Error;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String value[])
{
    (void)c, (void)vr, (void)value;
    return n == 0 ? fmi2OK : fmi2Error;
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String value[])
{
    (void)c, (void)vr, (void)value;
    return n == 0 ? fmi2OK : fmi2Error;
}

/* --- The state, for branches ---------------------------------------------------------------- */
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state)
{
    JointValues *copy = *state != NULL ? *state : malloc(sizeof *copy);
    if (copy == NULL) return fmi2Error;
    *copy = ((Joint *)c)->now;
    *state = copy;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state)
{
    if (state == NULL) return fmi2Error;
    ((Joint *)c)->now = *(JointValues *)state;
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state)
{
    (void)c;
    free(*state);
    *state = NULL;
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size)
{
    (void)c, (void)state;
    *size = sizeof(JointValues);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[], size_t size)
{
    (void)c;
    if (size < sizeof(JointValues)) return fmi2Error;
    memcpy(bytes, state, sizeof(JointValues));
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size, fmi2FMUstate *state)
{
    (void)c;
    if (size < sizeof(JointValues)) return fmi2Error;
    JointValues *copy = *state != NULL ? *state : malloc(sizeof *copy);
    if (copy == NULL) return fmi2Error;
    memcpy(copy, bytes, sizeof *copy);
    *state = copy;
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference unknown[], size_t n_unknown,
                                        const fmi2ValueReference known[], size_t n_known, const fmi2Real dv_known[],
                                        fmi2Real dv_unknown[])
{
    (void)c, (void)unknown, (void)n_unknown, (void)known, (void)n_known, (void)dv_known, (void)dv_unknown;
    return fmi2Error; /* providesDirectionalDerivative is false */
}

/* --- Co-simulation -------------------------------------------------------------------------- */
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    (void)c, (void)vr, (void)n, (void)order, (void)value;
    return fmi2Error; /* canInterpolateInputs is false */
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer order[], fmi2Real value[])
{
    (void)c, (void)vr, (void)n, (void)order, (void)value;
    return fmi2Error; /* maxOutputDerivativeOrder is 0 */
}

/* JointPlant.step over the communication step: the duty from motor_duty, clamped as an
 * H-bridge's (_plant.c's advance), held over the step. */
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real current, fmi2Real step, fmi2Boolean no_prior_state)
{
    (void)current, (void)no_prior_state;
    Joint *joint = c;
    JointValues *now = &joint->now;
    const double *coefficients = &now->v[VR_PLANT];
    double duty = now->v[VR_MOTOR_DUTY] / JOINT_MOTOR_DUTY_FULL_SCALE;
    if (!(isfinite(step) && step > 0.0) || !isfinite(duty)) {
        say(joint, fmi2Error, "doStep: the step and motor_duty must be finite, the step > 0");
        return fmi2Error;
    }
    if (duty > 1.0) duty = 1.0;
    if (duty < -1.0) duty = -1.0;
    double voltage = duty * coefficients[C_BUS_VOLTAGE];
    double x[X_COUNT];
    memcpy(x, now->x, sizeof x);
    if (joint_advance(coefficients, x, step, voltage, 0.0, 0, now->v[VR_AMBIENT]) < 0) {
        say(joint, fmi2Error, "doStep: the step needs more than 1e9 RK4 sub-steps");
        return fmi2Error;
    }
    for (int i = 0; i < X_COUNT; i++) {
        if (!isfinite(x[i])) {
            say(joint, fmi2Error, "doStep: the joint's state diverged (parameters far outside a joint's range)");
            return fmi2Error;
        }
    }
    JointValues next = *now;
    memcpy(next.x, x, sizeof x);
    next.time_s = now->time_s + step;
    if (update_outputs(&next, duty) < 0) {
        say(joint, fmi2Error, "doStep: no finite sensor readings");
        return fmi2Error;
    }
    *now = next;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c)
{
    (void)c;
    return fmi2Error;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind kind, fmi2Status *value)
{
    (void)c, (void)kind, (void)value;
    return fmi2Discard;
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind kind, fmi2Real *value)
{
    if (kind != fmi2LastSuccessfulTime) return fmi2Discard;
    *value = ((Joint *)c)->now.time_s;
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind kind, fmi2Integer *value)
{
    (void)c, (void)kind, (void)value;
    return fmi2Discard;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind kind, fmi2Boolean *value)
{
    (void)c, (void)kind, (void)value;
    return fmi2Discard;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind kind, fmi2String *value)
{
    (void)c, (void)kind, (void)value;
    return fmi2Discard;
}
