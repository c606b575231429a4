// Test-only physics of the demo joint, in double precision so that it is the
// truth the firmware's float estimates are measured against even after hours
// of simulated rotation: DC motor (voltage drive, back-EMF, winding inductance
// neglected), gearbox, series spring, load with viscous and smoothed Coulomb
// friction. The rig's JointParams defaults (rig/hilrig/physics/params.py).
// Encoders quantise like the hardware counters and wrap at 16 bits.
#pragma once

#include <cmath>
#include <cstdint>
#include <numbers>

namespace joint::testing {

class SeriesElasticPlant {
 public:
  static constexpr double kBusVoltageV = 24.0;
  static constexpr double kWindingResistanceOhm = 1.0;
  static constexpr double kTorqueConstantNmPerA = 0.05;
  static constexpr double kBackEmfVsPerRad = 0.05;
  static constexpr double kRotorInertiaKgM2 = 1e-5;
  static constexpr double kMotorFrictionNmsPerRad = 1e-6;
  static constexpr double kGearRatio = 50.0;
  static constexpr double kSpringNmPerRad = 50.0;
  static constexpr double kSpringDampingNmsPerRad = 0.02;
  static constexpr double kLoadInertiaKgM2 = 0.01;
  static constexpr double kLoadFrictionNmsPerRad = 0.01;
  static constexpr double kLoadCoulombNm = 0.05;
  static constexpr double kCoulombSmoothingRadS = 0.02;
  static constexpr double kMotorCountsPerRev = 4096.0;
  static constexpr double kOutputCountsPerRev = 16384.0;

  // Advances the plant by dt_s with the bridge at `duty` (-1..1), in substeps
  // short enough for semi-implicit Euler on the rotor's electrical damping.
  void step(double duty, double dt_s) {
    constexpr int kSubsteps = 4;
    const double h = dt_s / kSubsteps;
    for (int i = 0; i < kSubsteps; ++i) {
      current_a = (duty * kBusVoltageV - kBackEmfVsPerRad * motor_velocity_rad_s) / kWindingResistanceOhm;
      const double spring_nm = spring_torque_nm();
      const double motor_nm = kTorqueConstantNmPerA * current_a - kMotorFrictionNmsPerRad * motor_velocity_rad_s -
                              spring_nm / kGearRatio;
      const double load_nm = spring_nm - kLoadFrictionNmsPerRad * load_velocity_rad_s -
                             kLoadCoulombNm * std::tanh(load_velocity_rad_s / kCoulombSmoothingRadS);
      motor_velocity_rad_s += motor_nm / kRotorInertiaKgM2 * h;
      load_velocity_rad_s += load_nm / kLoadInertiaKgM2 * h;
      motor_angle_rad += motor_velocity_rad_s * h;
      load_angle_rad += load_velocity_rad_s * h;
    }
  }

  double spring_deflection_rad() const { return motor_angle_rad / kGearRatio - load_angle_rad; }
  double spring_torque_nm() const {
    return kSpringNmPerRad * spring_deflection_rad() +
           kSpringDampingNmsPerRad * (motor_velocity_rad_s / kGearRatio - load_velocity_rad_s);
  }

  // The encoders' 16-bit counters (floor: a count is reached, not rounded to).
  std::uint16_t motor_counts() const { return counter(motor_angle_rad, kMotorCountsPerRev); }
  std::uint16_t output_counts() const { return counter(load_angle_rad, kOutputCountsPerRev); }
  // The current ADC: 1 count per mA.
  std::int16_t current_ma() const {
    return static_cast<std::int16_t>(std::lround(std::fmax(-32768.0, std::fmin(32767.0, current_a * 1000.0))));
  }

  double motor_angle_rad = 0.0;
  double motor_velocity_rad_s = 0.0;
  double load_angle_rad = 0.0;
  double load_velocity_rad_s = 0.0;
  double current_a = 0.0;

 private:
  static std::uint16_t counter(double angle_rad, double counts_per_rev) {
    const auto counts = static_cast<std::int64_t>(std::floor(angle_rad / (2.0 * std::numbers::pi) * counts_per_rev));
    return static_cast<std::uint16_t>(counts & 0xFFFF);
  }
};

}  // namespace joint::testing
