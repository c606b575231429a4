/* The demo joint's physics without Python: the coefficient orders, the derivative and the RK4
 * step of the plant, and the sensor constants. Two users: the Python extension _plant.c (the
 * rig's joint) and _joint_fmu.c (the same joint as an FMI 2.0 co-simulation FMU, which
 * tools/joint_fmu.py builds). Both compile with -ffp-contract=off and without -ffast-math, so
 * the two give the same bits (see _plant.c on bit-identity with the Python reference).
 */
#ifndef HILRIG_JOINT_CORE_H
#define HILRIG_JOINT_CORE_H

#include <math.h>

/* Order of the plant's coefficient tuple (plant.py: plant_coefficients, by name). */
enum {
    C_RATIO,
    C_STIFFNESS,
    C_SPRING_DAMPING,
    C_INDUCTANCE,
    C_R_REF,
    C_ALPHA,
    C_T_REF,
    C_KT,
    C_KE,
    C_ROTOR_INERTIA,
    C_MOTOR_FRICTION,
    C_LOAD_INERTIA,
    C_LOAD_FRICTION,
    C_COULOMB,
    C_COULOMB_SPEED,
    C_THERMAL_CONDUCTANCE,
    C_THERMAL_CAPACITY,
    C_BUS_VOLTAGE,
    C_SUBSTEP_FRACTION,
    C_SUBSTEP_WITHOUT_ELECTRICAL,
    PLANT_COEFFICIENT_COUNT
};

/* Order of the sensors' coefficient tuple (sensors.py: sensor_coefficients, by name). */
enum {
    S_MOTOR_COUNTS_PER_REV,
    S_OUTPUT_COUNTS_PER_REV,
    S_NTC_R25,
    S_NTC_BETA,
    S_PULLUP,
    S_THERMISTOR_NOISE_COUNTS,
    S_CURRENT_NOISE_A,
    SENSOR_COEFFICIENT_COUNT
};

/* Indices into the integrator's state. */
enum { X_MOTOR_ANGLE, X_MOTOR_VELOCITY, X_LOAD_ANGLE, X_LOAD_VELOCITY, X_CURRENT, X_TEMPERATURE, X_COUNT };

/* Sensor constants, as in sensors.py. */
#define ENCODER_MODULUS 65536.0
#define THERMISTOR_ADC_MAX 4095.0
#define CURRENT_COUNTS_PER_A 1000.0
#define KELVIN_AT_0_C 273.15
#define NTC_REFERENCE_TEMPERATURE_K 298.15
#define I16_MIN -32768.0
#define I16_MAX 32767.0
/* Python's 2.0 * math.pi: the same double (doubling is exact). */
#define TWO_PI (2.0 * 3.141592653589793)

/* --- Plant physics ---------------------------------------------------------------------- */
static inline double winding_resistance(const double *c, double temperature_c)
{
    return c[C_R_REF] * (1.0 + c[C_ALPHA] * (temperature_c - c[C_T_REF]));
}

/* Longest RK4 sub-step from the present temperature [s]: L/R moves with R. */
static inline double max_substep(const double *c, double temperature_c)
{
    double resistance = winding_resistance(c, temperature_c);
    double electrical_s = resistance > 0.0 ? c[C_INDUCTANCE] / resistance : INFINITY;
    double electrical_limit = c[C_SUBSTEP_FRACTION] * electrical_s;
    /* Python's min(a, b): b only when strictly smaller. */
    return c[C_SUBSTEP_WITHOUT_ELECTRICAL] < electrical_limit ? c[C_SUBSTEP_WITHOUT_ELECTRICAL]
                                                              : electrical_limit;
}

/* Time derivative of the state for winding voltage and external load torque. */
static inline void derivative(const double *c, const double *x, double voltage, double load_torque,
                       int motor_held, double ambient, double *dx)
{
    double motor_angle = x[X_MOTOR_ANGLE], motor_vel = x[X_MOTOR_VELOCITY];
    double load_angle = x[X_LOAD_ANGLE], load_vel = x[X_LOAD_VELOCITY];
    double current = x[X_CURRENT], temperature = x[X_TEMPERATURE];
    double ratio = c[C_RATIO];
    double resistance = c[C_R_REF] * (1.0 + c[C_ALPHA] * (temperature - c[C_T_REF]));

    /* Spring between gearbox output (motor_angle / N) and load; reaches the rotor divided by N
     * (the gearbox is lossless here, its loss is the viscous term). */
    double spring_torque = c[C_STIFFNESS] * (motor_angle / ratio - load_angle)
                           + (c[C_SPRING_DAMPING] * (motor_vel / ratio - load_vel));
    double current_rate = (voltage - resistance * current - c[C_KE] * motor_vel) / c[C_INDUCTANCE];
    double motor_accel = 0.0;
    if (!motor_held) {
        motor_accel = (c[C_KT] * current - c[C_MOTOR_FRICTION] * motor_vel - spring_torque / ratio)
                      / c[C_ROTOR_INERTIA];
    }
    double friction = c[C_LOAD_FRICTION] * load_vel + c[C_COULOMB] * tanh(load_vel / c[C_COULOMB_SPEED]);
    double load_accel = (spring_torque - friction + load_torque) / c[C_LOAD_INERTIA];
    double heat_w = current * current * resistance;
    double temperature_rate = (heat_w - (temperature - ambient) * c[C_THERMAL_CONDUCTANCE])
                              / c[C_THERMAL_CAPACITY];

    dx[X_MOTOR_ANGLE] = motor_vel;
    dx[X_MOTOR_VELOCITY] = motor_accel;
    dx[X_LOAD_ANGLE] = load_vel;
    dx[X_LOAD_VELOCITY] = load_accel;
    dx[X_CURRENT] = current_rate;
    dx[X_TEMPERATURE] = temperature_rate;
}

/* The spring's deflection (gearbox output minus load) and the torque it applies to the load. */
static inline void joint_spring(const double *c, const double *x, double *deflection, double *torque)
{
    double ratio = c[C_RATIO];
    *deflection = x[X_MOTOR_ANGLE] / ratio - x[X_LOAD_ANGLE];
    *torque = c[C_STIFFNESS] * *deflection
              + c[C_SPRING_DAMPING] * (x[X_MOTOR_VELOCITY] / ratio - x[X_LOAD_VELOCITY]);
}

/* Advances the state `x` by `dt_s` (finite, > 0) with the winding at `voltage`: RK4 in
 * sub-steps of at most max_substep at the step's start temperature. -1 (x untouched): more
 * than 1e9 sub-steps. */
static inline int joint_advance(const double *c, double *x, double dt_s, double voltage,
                                double load_torque, int motor_held, double ambient)
{
    double substep_count = ceil(dt_s / max_substep(c, x[X_TEMPERATURE]) - 1e-9);
    if (substep_count < 1.0) substep_count = 1.0;
    if (!(substep_count <= 1e9)) return -1;
    long substeps = (long)substep_count;
    double h = dt_s / (double)substeps;
    double half = 0.5 * h;
    double sixth = h / 6.0;
    double k1[X_COUNT], k2[X_COUNT], k3[X_COUNT], k4[X_COUNT], probe[X_COUNT];
    for (long n = 0; n < substeps; n++) {
        derivative(c, x, voltage, load_torque, motor_held, ambient, k1);
        for (int i = 0; i < X_COUNT; i++) probe[i] = x[i] + half * k1[i];
        derivative(c, probe, voltage, load_torque, motor_held, ambient, k2);
        for (int i = 0; i < X_COUNT; i++) probe[i] = x[i] + half * k2[i];
        derivative(c, probe, voltage, load_torque, motor_held, ambient, k3);
        for (int i = 0; i < X_COUNT; i++) probe[i] = x[i] + h * k3[i];
        derivative(c, probe, voltage, load_torque, motor_held, ambient, k4);
        for (int i = 0; i < X_COUNT; i++) x[i] = x[i] + sixth * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
    }
    return 0;
}

/* --- Sensors (sensors.py's conversions; finite inputs: the callers check) ------------------ */
/* sensors.round_half_away (C's lround), then saturated to [low, high]. */
static inline double joint_round_saturated(double value, double low, double high)
{
    double rounded = copysign(floor(fabs(value) + 0.5), value);
    if (rounded < low) rounded = low;
    if (rounded > high) rounded = high;
    return rounded;
}

/* sensors.encoder_counts before the wrap: the floor of the position in counts. */
static inline double joint_encoder_position(double angle_rad, double counts_per_rev)
{
    return floor(angle_rad * counts_per_rev / TWO_PI);
}

/* sensors.encoder_counts of a floored count: wrapped to U16 (exact; Python's % is
 * non-negative). */
static inline double joint_wrapped_counts(double counts)
{
    double wrapped = fmod(counts, ENCODER_MODULUS);
    if (wrapped < 0.0) wrapped += ENCODER_MODULUS;
    return wrapped;
}

/* sensors.ntc_resistance and thermistor_adc_exact from the NTC's exponent: unrounded ADC
 * counts. */
static inline double joint_thermistor_adc(const double *s, double growth)
{
    double ntc_ohm = s[S_NTC_R25] * growth;
    return THERMISTOR_ADC_MAX * ntc_ohm / (ntc_ohm + s[S_PULLUP]);
}

/* The exponent of the NTC's beta model at `temperature_k` (not 0). */
static inline double joint_ntc_exponent(const double *s, double temperature_k)
{
    return s[S_NTC_BETA] * (1.0 / temperature_k - 1.0 / NTC_REFERENCE_TEMPERATURE_K);
}

#endif /* HILRIG_JOINT_CORE_H */
