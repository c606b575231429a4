// Stand-ins for the demo joint's components, shaped like them (4 sensors,
// 5 virtual sensors, 6 modules, 2 actuators, similar float math), so the
// benchmark measures a realistic cycle. The real components in
// firmware/joint/ will replace them.
//
// Each component's math is a small struct with a templated step(io): the same
// math runs on the core's MessageBoard and on the naive string-keyed board,
// so the two cycles differ only in the board.
#pragma once

#include <cmath>
#include <cstdint>
#include <numbers>
#include <string_view>
#include <utility>

#include "board/fields.hpp"
#include "core/LatestValueRegister.hpp"
#include "core/MessageBoardUser.hpp"
#include "core/SampleBuffer.hpp"

namespace bench {

using F = board::FieldId;
using core::ComponentKind;
using core::Declarations;

inline constexpr float kCyclePeriodS = 0.001f;

// What the receive path fills (raw values as the hardware gives them) and
// what the actuators produce.
struct Hardware {
  core::LatestValueRegister<std::uint16_t> motor_encoder_counts;
  core::LatestValueRegister<std::uint16_t> output_encoder_counts;
  core::LatestValueRegister<std::uint16_t> thermistor_adc;
  core::SampleBuffer<std::int16_t, 16> motor_current_ma;
  std::int16_t motor_duty = 0;
  std::uint8_t led_pattern = 0;
};

// --- sensors ----------------------------------------------------------------

// Unwraps a 16-bit counter into a position in radians.
struct EncoderMath {
  core::LatestValueRegister<std::uint16_t>* counts;
  F position_field;
  F counts_per_rev_field;
  std::int64_t accumulated = 0;
  std::uint16_t previous = 0;

  template <typename Io>
  void step(Io& io) {
    const auto reading = counts->read();
    accumulated += static_cast<std::int16_t>(static_cast<std::uint16_t>(reading.value - previous));
    previous = reading.value;
    const float counts_per_rev = io.get(counts_per_rev_field);
    io.set(position_field, static_cast<float>(accumulated) * (2.0f * std::numbers::pi_v<float>) / counts_per_rev);
  }
};

struct ThermistorMath {
  core::LatestValueRegister<std::uint16_t>* adc;
  template <typename Io>
  void step(Io& io) {
    constexpr float kPullupOhm = 10'000.0f;
    const float counts = static_cast<float>(adc->read().value);
    const float clamped = std::fmin(std::fmax(counts, 1.0f), 4094.0f);
    io.set(F::thermistor_resistance, kPullupOhm * clamped / (4095.0f - clamped));
  }
};

struct CurrentMath {
  core::SampleBuffer<std::int16_t, 16>* samples_ma;
  float last_amps = 0.0f;
  template <typename Io>
  void step(Io& io) {
    std::int32_t sum = 0;
    const std::size_t count = samples_ma->drain([&](std::int16_t sample) { sum += sample; });
    if (count != 0) {
      last_amps = static_cast<float>(sum) / static_cast<float>(count) / 1000.0f;
    }
    io.set(F::motor_current, last_amps);
  }
};

// --- virtual sensors --------------------------------------------------------

struct VelocityMath {
  F position_field;
  F velocity_field;
  float previous_position = 0.0f;
  float filtered = 0.0f;
  template <typename Io>
  void step(Io& io) {
    const float position = io.get(position_field);
    const float raw = (position - previous_position) / kCyclePeriodS;
    previous_position = position;
    const float alpha = 1.0f - std::exp(-2.0f * std::numbers::pi_v<float> * io.get(F::velocity_filter_hz) * kCyclePeriodS);
    filtered += alpha * (raw - filtered);
    io.set(velocity_field, filtered);
  }
};

struct SpringDeflectionMath {
  template <typename Io>
  void step(Io& io) {
    io.set(F::spring_deflection, io.get(F::motor_position) / io.get(F::gear_ratio) - io.get(F::output_position));
  }
};

struct JointTorqueMath {
  template <typename Io>
  void step(Io& io) {
    io.set(F::joint_torque, io.get(F::spring_constant_nominal) * io.get(F::spring_deflection));
  }
};

struct WindingTemperatureMath {
  template <typename Io>
  void step(Io& io) {
    constexpr float kKelvinAt25C = 298.15f;
    const float resistance = io.get(F::thermistor_resistance);
    const float inverse_t = 1.0f / kKelvinAt25C + std::log(resistance / io.get(F::ntc_r25_ohm)) / io.get(F::ntc_beta_k);
    io.set(F::winding_temperature, 1.0f / inverse_t - 273.15f);
  }
};

// --- modules ------------------------------------------------------------------

struct ThermalProtectionMath {
  bool limiting = false;
  template <typename Io>
  void step(Io& io) {
    const float temperature = io.get(F::winding_temperature);
    const float warning = io.get(F::thermal_warning_c);
    const float limit = io.get(F::thermal_limit_c);
    if (temperature >= limit) {
      limiting = true;
    } else if (temperature < limit - io.get(F::thermal_hysteresis_c)) {
      limiting = false;
    }
    const float ramp = 1.0f - (temperature - warning) / (limit - warning);
    io.set(F::thermal_derate, limiting ? 0.0f : std::fmin(1.0f, std::fmax(0.0f, ramp)));
  }
};

struct SafetySupervisorMath {
  std::uint32_t latched = 0;
  template <typename Io>
  void step(Io& io) {
    const bool watchdog = io.is_stale(F::velocity_setpoint, static_cast<std::uint32_t>(io.get(F::watchdog_cycles)));
    const bool encoder = io.is_stale(F::motor_position, static_cast<std::uint32_t>(io.get(F::encoder_stale_cycles)));
    const bool overheated = io.get(F::thermal_derate) <= 0.0f;
    if (io.get(F::fault_clear) >= 0.5f) {
      latched = 0;
    }
    latched |= (watchdog ? 1U : 0U) | (encoder ? 2U : 0U) | (overheated ? 4U : 0U);
    io.set(F::watchdog_tripped, watchdog ? 1.0f : 0.0f);
    io.set(F::fault_flags, static_cast<float>(latched));
    io.set(F::safe_state, latched != 0 ? 1.0f : 0.0f);
    const float mode = io.get(F::control_mode);
    io.set(F::led_pattern_command, latched != 0 ? 3.0f : (mode == 0.0f ? 2.0f : 1.0f));
  }
};

struct VelocityControllerMath {
  float integral = 0.0f;
  float previous_error = 0.0f;
  template <typename Io>
  void step(Io& io) {
    const float error = io.get(F::velocity_setpoint) - io.get(F::motor_velocity);
    const float max_duty = io.get(F::max_duty);
    // Anti-windup from what the motor actually got last cycle.
    if (std::fabs(io.get(F::motor_duty_command)) < max_duty) {
      integral += error * kCyclePeriodS;
    }
    const float derivative = (error - previous_error) / kCyclePeriodS;
    previous_error = error;
    const float output = io.get(F::velocity_kp) * error + io.get(F::velocity_ki) * integral +
                         io.get(F::velocity_kd) * derivative;
    io.set(F::velocity_controller_output, std::fmin(max_duty, std::fmax(-max_duty, output)));
  }
};

struct TorqueControllerMath {
  float integral = 0.0f;
  template <typename Io>
  void step(Io& io) {
    const float error = io.get(F::torque_setpoint) - io.get(F::joint_torque);
    const float max_duty = io.get(F::max_duty);
    integral = std::fmin(max_duty, std::fmax(-max_duty, integral + io.get(F::torque_ki) * error * kCyclePeriodS));
    io.set(F::torque_controller_output, std::fmin(max_duty, std::fmax(-max_duty, io.get(F::torque_kp) * error + integral)));
  }
};

struct DriveArbiterMath {
  template <typename Io>
  void step(Io& io) {
    float duty = 0.0f;
    const auto mode = static_cast<int>(io.get(F::control_mode));
    if (mode == 1) {
      duty = io.get(F::velocity_controller_output);
    } else if (mode == 2) {
      duty = io.get(F::torque_controller_output);
    }
    if (io.get(F::safe_state) >= 0.5f) {
      duty = 0.0f;
    }
    io.set(F::motor_duty_command, duty * io.get(F::thermal_derate));
  }
};

// Recursive estimate of the spring constant from motor current and deflection.
struct SpringEstimatorMath {
  float estimate = 0.0f;
  float covariance = 1000.0f;
  template <typename Io>
  void step(Io& io) {
    constexpr float kTorquePerAmp = 0.05f;
    constexpr float kForgetting = 0.999f;
    const float deflection = io.get(F::spring_deflection);
    const float torque = kTorquePerAmp * io.get(F::motor_current) * io.get(F::gear_ratio);
    const float gain = covariance * deflection / (kForgetting + deflection * covariance * deflection);
    estimate += gain * (torque - deflection * estimate);
    covariance = (covariance - gain * deflection * covariance) / kForgetting;
    io.set(F::spring_constant_estimate, estimate);
    io.set(F::spring_constant_confidence, 1.0f / (1.0f + covariance));
  }
};

// --- actuators ----------------------------------------------------------------

struct MotorMath {
  Hardware* hardware;
  template <typename Io>
  void step(Io& io) {
    hardware->motor_duty = static_cast<std::int16_t>(std::lround(io.get(F::motor_duty_command) * 10000.0f));
  }
};

struct LedMath {
  Hardware* hardware;
  template <typename Io>
  void step(Io& io) {
    hardware->led_pattern = static_cast<std::uint8_t>(io.get(F::led_pattern_command));
  }
};

// --- the joint ------------------------------------------------------------------

// Calls make(kind, name, declarations, math) for every component, in an order
// unrelated to the update order (the scheduler finds that).
template <typename Make>
void build_joint(Hardware& hardware, Make&& make) {
  make(ComponentKind::Actuator, "motor", Declarations{.reads = {F::motor_duty_command}}, MotorMath{&hardware});
  make(ComponentKind::Actuator, "led", Declarations{.reads = {F::led_pattern_command}}, LedMath{&hardware});
  make(ComponentKind::Module, "drive_arbiter",
       Declarations{.writes = {F::motor_duty_command},
                    .reads = {F::control_mode, F::velocity_controller_output, F::torque_controller_output,
                              F::safe_state, F::thermal_derate}},
       DriveArbiterMath{});
  make(ComponentKind::Module, "velocity_controller",
       Declarations{.writes = {F::velocity_controller_output},
                    .reads = {F::velocity_setpoint, F::motor_velocity, F::max_duty, F::velocity_kp, F::velocity_ki,
                              F::velocity_kd},
                    .reads_last_cycle = {F::motor_duty_command}},
       VelocityControllerMath{});
  make(ComponentKind::Module, "torque_controller",
       Declarations{.writes = {F::torque_controller_output},
                    .reads = {F::torque_setpoint, F::joint_torque, F::max_duty, F::torque_kp, F::torque_ki}},
       TorqueControllerMath{});
  make(ComponentKind::Module, "safety_supervisor",
       Declarations{.writes = {F::watchdog_tripped, F::fault_flags, F::safe_state, F::led_pattern_command},
                    .reads = {F::velocity_setpoint, F::motor_position, F::watchdog_cycles, F::encoder_stale_cycles,
                              F::thermal_derate, F::fault_clear, F::control_mode}},
       SafetySupervisorMath{});
  make(ComponentKind::Module, "thermal_protection",
       Declarations{.writes = {F::thermal_derate},
                    .reads = {F::winding_temperature, F::thermal_warning_c, F::thermal_limit_c,
                              F::thermal_hysteresis_c}},
       ThermalProtectionMath{});
  make(ComponentKind::Module, "spring_estimator",
       Declarations{.writes = {F::spring_constant_estimate, F::spring_constant_confidence},
                    .reads = {F::spring_deflection, F::motor_current, F::gear_ratio}},
       SpringEstimatorMath{});
  make(ComponentKind::VirtualSensor, "joint_torque",
       Declarations{.writes = {F::joint_torque}, .reads = {F::spring_deflection, F::spring_constant_nominal}},
       JointTorqueMath{});
  make(ComponentKind::VirtualSensor, "spring_deflection",
       Declarations{.writes = {F::spring_deflection}, .reads = {F::motor_position, F::output_position, F::gear_ratio}},
       SpringDeflectionMath{});
  make(ComponentKind::VirtualSensor, "motor_velocity",
       Declarations{.writes = {F::motor_velocity}, .reads = {F::motor_position, F::velocity_filter_hz}},
       VelocityMath{F::motor_position, F::motor_velocity});
  make(ComponentKind::VirtualSensor, "output_velocity",
       Declarations{.writes = {F::output_velocity}, .reads = {F::output_position, F::velocity_filter_hz}},
       VelocityMath{F::output_position, F::output_velocity});
  make(ComponentKind::VirtualSensor, "winding_temperature",
       Declarations{.writes = {F::winding_temperature},
                    .reads = {F::thermistor_resistance, F::ntc_r25_ohm, F::ntc_beta_k}},
       WindingTemperatureMath{});
  make(ComponentKind::Sensor, "motor_encoder",
       Declarations{.writes = {F::motor_position}, .reads = {F::encoder_counts_per_rev}},
       EncoderMath{&hardware.motor_encoder_counts, F::motor_position, F::encoder_counts_per_rev});
  make(ComponentKind::Sensor, "output_encoder",
       Declarations{.writes = {F::output_position}, .reads = {F::output_encoder_counts_per_rev}},
       EncoderMath{&hardware.output_encoder_counts, F::output_position, F::output_encoder_counts_per_rev});
  make(ComponentKind::Sensor, "thermistor", Declarations{.writes = {F::thermistor_resistance}},
       ThermistorMath{&hardware.thermistor_adc});
  make(ComponentKind::Sensor, "motor_current", Declarations{.writes = {F::motor_current}},
       CurrentMath{&hardware.motor_current_ma});
}

// What the receive path would do between cycles: new raw values, four
// current samples per cycle (oversampled).
inline void feed_hardware(Hardware& hardware, std::uint32_t cycle) {
  hardware.motor_encoder_counts.write(static_cast<std::uint16_t>(cycle * 7U));
  hardware.output_encoder_counts.write(static_cast<std::uint16_t>(cycle * 3U));
  hardware.thermistor_adc.write(static_cast<std::uint16_t>(2000U + (cycle & 15U)));
  for (std::int16_t i = 0; i < 4; ++i) {
    hardware.motor_current_ma.push(static_cast<std::int16_t>(500 + i));
  }
}

// A joint-like component on the core board: its math runs in update() through get/set/is_stale.
// (Used by the Google Benchmark suite and by the callgrind cycle counter.)
template <typename Math>
class CoreAdapter final : public core::MessageBoardUser {
 public:
  CoreAdapter(core::MessageBoard& board, ComponentKind kind, std::string_view name, const Declarations& declarations,
              Math math)
      : MessageBoardUser(board, kind, name, declarations), math_{std::move(math)} {}
  void update() override { math_.step(*this); }

  float get(F id) const { return boardGet(id); }
  void set(F id, float value) { boardSet(id, value); }
  bool is_stale(F id, std::uint32_t max_age_cycles) const { return boardIsStale(id, max_age_cycles); }

 private:
  Math math_;
};

}  // namespace bench
