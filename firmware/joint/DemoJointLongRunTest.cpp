// The demo joint's components on a double-precision plant for as long as a
// joint turns on a test bench: estimates must not degrade with the
// distance turned or the cycles counted. Its own binary with the ctest label
// long_run, as it runs millions of cycles; no bus, no wall-clock time.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>

#include "core/CycleCounter.hpp"
#include "core/Scheduler.hpp"
#include "joint/DemoJoint.hpp"
#include "joint/FaultBits.hpp"
#include "joint/drivers/HilRegisters.hpp"
#include "joint/testing/BoardStandIns.hpp"
#include "joint/testing/SeriesElasticPlant.hpp"

namespace joint {
namespace {

using board::FieldId;
using testing::SeriesElasticPlant;

using joint::testing::kDtS;
constexpr std::uint64_t kCyclesPerSecond = 1000;
constexpr double kPi = std::numbers::pi;

// The firmware's side of the HIL loop in one object: sensor frame and setpoint
// frame in before each cycle, the cycle, the plant stepped with the duty out.
class JointOnPlant {
 public:
  JointOnPlant() {
    EXPECT_TRUE(joint.add_to(scheduler));
    EXPECT_TRUE(scheduler.add(bus));
    const core::StartupStatus status = scheduler.start();
    EXPECT_TRUE(status) << status.message();
    write(FieldId::control_mode, 1.0F);  // velocity
  }

  void write(FieldId id, float value) { EXPECT_EQ(bus.write(id, value), core::SetResult::Ok); }

  // One cycle `periods` control periods after the previous one; the plant moves
  // only `plant_dt_s` (a jumped cycle counter need not mean time for the plant).
  void run_cycle(std::uint64_t periods, double plant_dt_s) {
    sampled = plant;  // what this cycle's sensor frame shows
    if (motor_encoder_live) registers.write_motor_encoder(plant.motor_counts());
    if (output_encoder_live) registers.write_output_encoder(plant.output_counts());
    registers.write_thermistor_adc(2048);  // 25 degC
    registers.write_motor_current(plant.current_ma());
    if (streaming_setpoints) {
      write(FieldId::velocity_setpoint, velocity_setpoint_rad_s);
      write(FieldId::torque_setpoint, 0.0F);
    }
    scheduler.run_cycle(cycles.advance(periods));
    plant.step(registers.motor_duty_raw() / 10000.0, plant_dt_s);
  }
  void run_cycle() { run_cycle(1, kDtS); }

  float get(FieldId id) const { return board.get(id); }
  std::uint32_t fault_flags() const { return static_cast<std::uint32_t>(board.get(FieldId::fault_flags)); }

  core::MessageBoard board;
  core::Scheduler scheduler{board};
  HilRegisters registers;
  DemoJoint joint{board, registers.drivers(), kDtS};
  testing::BusStandIn bus{board};
  SeriesElasticPlant plant;
  SeriesElasticPlant sampled;  // the plant as the last cycle's sensor frame saw it
  core::CycleCounter cycles;
  float velocity_setpoint_rad_s = 0.0F;
  bool streaming_setpoints = true;
  bool motor_encoder_live = true;
  bool output_encoder_live = true;
};

// The most a first-order filter's output moves on one count of encoder
// quantisation in one cycle: alpha * (one count / dt) [rad/s]. The estimate
// cannot be nearer the truth than that at every single cycle, whatever the arithmetic.
double quantisation_bound_rad_s(double counts_per_rev, double cutoff_hz) {
  const double alpha = 1.0 - std::exp(-2.0 * kPi * cutoff_hz * kDtS);
  return alpha * (2.0 * kPi / counts_per_rev) / kDtS;
}

// Error statistics of an estimate against the plant's truth over a stretch of cycles.
struct ErrorWindow {
  // Instantaneous |estimate - truth|, worst cycle [same unit as the values].
  double worst_instant = 0.0;
  // |mean(estimate) - mean(truth)| over each block of kBlock cycles, worst block,
  // relative to the block's mean truth: averages the count quantisation away (one
  // count per block) and nothing else (the filter's time constant is 1.6 ms).
  static constexpr int kBlock = 100;
  double worst_block_relative = 0.0;
  double estimate_sum = 0.0;
  double truth_sum = 0.0;
  int in_block = 0;

  void add(double estimate, double truth) {
    worst_instant = std::max(worst_instant, std::fabs(estimate - truth));
    estimate_sum += estimate;
    truth_sum += truth;
    if (++in_block == kBlock) {
      worst_block_relative =
          std::max(worst_block_relative, std::fabs(estimate_sum - truth_sum) / std::fabs(truth_sum));
      estimate_sum = truth_sum = 0.0;
      in_block = 0;
    }
  }
};

// Two hours of continuous rotation at the joint's top speed (velocity setpoint
// beyond reach, the loop saturated at max_duty): 7.2 million cycles, the motor
// turns 3.3e6 rad. A velocity estimate that differentiates float angles fails
// it: their resolution coarsens as the angle grows, so the last minute's 0.1 s
// means drift off the first minute's and single cycles jump.
TEST(DemoJointLongRun, TwoHoursAtTopSpeedKeepEveryEstimateAsGoodAsInTheFirstMinute) {
  JointOnPlant rig;
  rig.velocity_setpoint_rad_s = 50.0F;  // the table's maximum: more than the motor can give
  constexpr std::uint64_t kTwoHours = 7'200'000;
  constexpr std::uint64_t kMinute = 60 * kCyclesPerSecond;
  const double motor_bound = quantisation_bound_rad_s(SeriesElasticPlant::kMotorCountsPerRev, 100.0);
  const double output_bound = quantisation_bound_rad_s(SeriesElasticPlant::kOutputCountsPerRev, 100.0);
  // One count of either encoder, seen at the spring.
  const double deflection_bound = 2.0 * kPi / (SeriesElasticPlant::kMotorCountsPerRev * SeriesElasticPlant::kGearRatio) +
                                  2.0 * kPi / SeriesElasticPlant::kOutputCountsPerRev;

  ErrorWindow motor_first, motor_last, output_first, output_last;
  double deflection_first = 0.0, deflection_last = 0.0;
  std::uint32_t faults_seen = 0;
  for (std::uint64_t n = 1; n <= kTwoHours; ++n) {
    rig.run_cycle();
    faults_seen |= rig.fault_flags();
    // Skip the acceleration (the first second); then the first minute and the last.
    const bool first = n > kCyclesPerSecond && n <= kCyclesPerSecond + kMinute;
    const bool last = n > kTwoHours - kMinute;
    if (!first && !last) continue;
    (first ? motor_first : motor_last).add(rig.get(FieldId::motor_velocity), rig.sampled.motor_velocity_rad_s);
    (first ? output_first : output_last).add(rig.get(FieldId::output_velocity), rig.sampled.load_velocity_rad_s);
    double& deflection = first ? deflection_first : deflection_last;
    deflection =
        std::max(deflection, std::fabs(rig.get(FieldId::spring_deflection) - rig.sampled.spring_deflection_rad()));
  }
  const double motor_speed = rig.plant.motor_velocity_rad_s;
  ASSERT_GT(motor_speed, 400.0) << "the joint did not run at top speed";
  EXPECT_GT(rig.plant.motor_angle_rad, 3.0e6) << "two hours at top speed";
  EXPECT_EQ(faults_seen, 0U) << "fault bits latched during the run";

  RecordProperty("motor_velocity_worst_block_error_pct_first_minute", std::to_string(100 * motor_first.worst_block_relative));
  RecordProperty("motor_velocity_worst_block_error_pct_last_minute", std::to_string(100 * motor_last.worst_block_relative));
  std::printf("motor_velocity: worst 0.1 s mean error %.4f %% first minute, %.4f %% last minute; worst single cycle "
              "%.3f / %.3f rad/s (quantisation bound %.3f) at %.2f rad/s\n",
              100 * motor_first.worst_block_relative, 100 * motor_last.worst_block_relative, motor_first.worst_instant,
              motor_last.worst_instant, motor_bound, motor_speed);
  std::printf("output_velocity: worst 0.1 s mean error %.4f %% first minute, %.4f %% last minute; worst single cycle "
              "%.4f / %.4f rad/s (quantisation bound %.4f)\n",
              100 * output_first.worst_block_relative, 100 * output_last.worst_block_relative, output_first.worst_instant,
              output_last.worst_instant, output_bound);
  std::printf("spring_deflection: worst error %.2e rad first minute, %.2e rad last minute (one count: %.2e rad)\n",
              deflection_first, deflection_last, deflection_bound);

  // The goal: within 0.1 % of the truth at the end.
  EXPECT_LT(motor_last.worst_block_relative, 0.001) << "motor_velocity, 0.1 s means, last minute of two hours";
  EXPECT_LT(output_last.worst_block_relative, 0.001) << "output_velocity, 0.1 s means, last minute of two hours";
  // Cycle by cycle, no worse than the encoder's quantisation allows (plus 0.1 %).
  EXPECT_LT(motor_last.worst_instant, motor_bound + 0.001 * motor_speed) << "motor_velocity, single cycles";
  EXPECT_LT(output_last.worst_instant, output_bound + 0.001 * motor_speed / SeriesElasticPlant::kGearRatio)
      << "output_velocity, single cycles";
  EXPECT_LT(deflection_last, deflection_bound) << "spring_deflection, last minute";
  EXPECT_NEAR(rig.get(FieldId::joint_torque), 50.0 * rig.sampled.spring_deflection_rad(), 50.0 * deflection_bound);

  // The velocity loop held max_duty for two hours: its integrator is bounded by
  // the limit, so a lower setpoint is followed at once (no wind-up to unwind).
  EXPECT_FLOAT_EQ(rig.get(FieldId::motor_duty_command), rig.get(FieldId::max_duty));
  rig.velocity_setpoint_rad_s = 5.0F;
  for (int n = 0; n < 500; ++n) rig.run_cycle();
  EXPECT_NEAR(rig.plant.motor_velocity_rad_s / SeriesElasticPlant::kGearRatio, 5.0, 0.1)
      << "0.5 s after the setpoint dropped from saturation to 5 rad/s";

  // The spring-constant estimator ran on two hours of unexciting data: its
  // outputs stay finite and in range.
  const float k = rig.get(FieldId::spring_constant_estimate);
  const float confidence = rig.get(FieldId::spring_constant_confidence);
  EXPECT_TRUE(std::isfinite(k) && k >= 0.0F && k <= 10000.0F) << k;
  EXPECT_TRUE(std::isfinite(confidence) && confidence >= 0.0F && confidence <= 1.0F) << confidence;
}

// The 32-bit cycle number wraps after 2^32 cycles (49.7 days at 1 kHz). The
// joint runs from cycle 1, then its counter jumps (a free-running firmware
// suspended for 49.7 days wakes up late by that many periods: the watchdog
// trips, as it should, and is cleared), so that the wrap of the cycle number
// and of "cycles since start" both come while the joint turns at top speed.
// Across them: velocity as good as quantisation allows, no spurious fault, and
// a silent encoder and a silent setpoint stream detected on the exact cycle.
TEST(DemoJointLongRun, CrossesThe2To32CycleWrapWithoutAGlitch) {
  JointOnPlant rig;
  rig.velocity_setpoint_rad_s = 50.0F;
  rig.write(FieldId::encoder_stale_cycles, 20.0F);
  rig.write(FieldId::watchdog_cycles, 50.0F);
  for (int n = 0; n < 2000; ++n) rig.run_cycle();
  ASSERT_EQ(rig.fault_flags(), 0U);

  constexpr std::uint32_t kBeforeWrap = 3000;
  rig.run_cycle((std::uint64_t{1} << 32) - kBeforeWrap - rig.cycles.cycle(), kDtS);
  ASSERT_EQ(rig.cycles.cycle(), 0U - kBeforeWrap);
  EXPECT_EQ(rig.fault_flags(), fault_mask(FaultBit::CommandWatchdog)) << "49.7 days without a setpoint";
  rig.write(FieldId::fault_clear, 1.0F);
  for (std::uint32_t n = 0; n < 2000; ++n) rig.run_cycle();  // back to top speed
  ASSERT_EQ(rig.fault_flags(), 0U);

  const double motor_bound = quantisation_bound_rad_s(SeriesElasticPlant::kMotorCountsPerRev, 100.0);
  double worst_motor_error = 0.0;
  // Up to 5 cycles before the wrap everything is live; then the output encoder
  // and the setpoint stream fall silent and the counter wraps.
  while (rig.cycles.cycle() != 0U - 5U) {
    rig.run_cycle();
    worst_motor_error = std::max(worst_motor_error, std::fabs(rig.get(FieldId::motor_velocity) - rig.sampled.motor_velocity_rad_s));
  }
  ASSERT_EQ(rig.fault_flags(), 0U);
  rig.output_encoder_live = false;
  rig.streaming_setpoints = false;
  for (int silent = 1; silent <= 50; ++silent) {
    rig.run_cycle();
    const std::uint32_t expected = (silent >= 20 ? fault_mask(FaultBit::OutputEncoderStale) : 0U) |
                                   (silent >= 50 ? fault_mask(FaultBit::CommandWatchdog) : 0U);
    ASSERT_EQ(rig.fault_flags(), expected) << silent << " cycles of silence, at cycle " << rig.cycles.cycle();
    if (silent < 20) {  // the drive is still on: the speed holds
      worst_motor_error =
          std::max(worst_motor_error, std::fabs(rig.get(FieldId::motor_velocity) - rig.sampled.motor_velocity_rad_s));
    }
  }
  EXPECT_EQ(rig.get(FieldId::watchdog_tripped), 1.0F) << "50 cycles without a setpoint, at cycle " << rig.cycles.cycle();
  EXPECT_LT(worst_motor_error, motor_bound + 0.001 * rig.plant.motor_velocity_rad_s)
      << "motor_velocity across the wrap, single cycles";
}

// The soak's sensor pattern (rig/hilrig/soak.py SensorPattern: the motor
// counter advancing 25 counts per cycle, the output counter 2) for its million
// cycles, without the bus: the velocity estimates it reads back, sampled every
// 1000 cycles as the soak does, in its first and last tenth: exact in both,
// where an estimate that loses resolution with the count drifts in the last.
TEST(DemoJointLongRun, SoakPatternVelocityIsExactForAMillionCycles) {
  JointOnPlant rig;
  constexpr std::uint32_t kMotorCountsPerCycle = 25;
  constexpr std::uint32_t kOutputCountsPerCycle = 2;  // 25 * 16384 / (4096 * 50)
  const double expected_motor = kMotorCountsPerCycle / 4096.0 * 2.0 * kPi / kDtS;
  const double expected_output = kOutputCountsPerCycle / 16384.0 * 2.0 * kPi / kDtS;
  rig.velocity_setpoint_rad_s = static_cast<float>(expected_output);
  constexpr std::uint32_t kCycles = 1'000'000;
  double worst_first_pct = 0.0, worst_last_pct = 0.0, worst_output_pct = 0.0;
  for (std::uint32_t n = 1; n <= kCycles; ++n) {
    rig.registers.write_motor_encoder(static_cast<std::uint16_t>(n * kMotorCountsPerCycle));
    rig.registers.write_output_encoder(static_cast<std::uint16_t>(n * kOutputCountsPerCycle));
    rig.registers.write_thermistor_adc(2048);
    rig.registers.write_motor_current(0);
    rig.write(FieldId::velocity_setpoint, rig.velocity_setpoint_rad_s);
    rig.write(FieldId::torque_setpoint, 0.0F);
    rig.scheduler.run_cycle(rig.cycles.advance());
    if (n % 1000 != 0 || n < 1000) continue;
    const double motor_pct = 100.0 * std::fabs(rig.get(FieldId::motor_velocity) - expected_motor) / expected_motor;
    const double output_pct = 100.0 * std::fabs(rig.get(FieldId::output_velocity) - expected_output) / expected_output;
    if (n <= kCycles / 10) worst_first_pct = std::max(worst_first_pct, motor_pct);
    if (n > kCycles - kCycles / 10) worst_last_pct = std::max(worst_last_pct, motor_pct);
    worst_output_pct = std::max(worst_output_pct, output_pct);
  }
  std::printf("soak pattern: motor_velocity max error %.5f %% first tenth, %.5f %% last tenth; output_velocity %.5f %%\n",
              worst_first_pct, worst_last_pct, worst_output_pct);
  EXPECT_LT(worst_first_pct, 0.1);
  EXPECT_LT(worst_last_pct, 0.1);
  EXPECT_LT(worst_output_pct, 0.1);
}

}  // namespace
}  // namespace joint
