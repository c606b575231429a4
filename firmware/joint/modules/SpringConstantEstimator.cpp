#include "joint/modules/SpringConstantEstimator.hpp"

#include <algorithm>
#include <cmath>

#include "joint/BoardReads.hpp"

namespace joint {

using board::FieldId;

SpringConstantEstimator::SpringConstantEstimator(core::MessageBoard& board, float dt_s)
    : Module(board, "spring_constant_estimator",
             {.writes = {FieldId::spring_constant_estimate, FieldId::spring_constant_confidence},
              .reads = {FieldId::motor_current, FieldId::motor_torque_constant, FieldId::spring_deflection, FieldId::motor_velocity,
                        FieldId::gear_ratio, FieldId::spring_constant_nominal}}),
      dt_s_{dt_s} {}

bool SpringConstantEstimator::quasi_static_sample() {
  const core::MessageBoard& b = board();
  if (!written_this_cycle(b, FieldId::motor_velocity)) {
    return false;
  }
  const float velocity_rad_s = boardGet(FieldId::motor_velocity);
  const bool had_previous = has_previous_velocity_;
  const float elapsed_s = static_cast<float>(b.cycle() - previous_velocity_cycle_) * dt_s_;
  const float acceleration_rad_s2 = had_previous && elapsed_s > 0.0F
                                        ? (velocity_rad_s - previous_motor_velocity_rad_s_) / elapsed_s
                                        : 0.0F;
  has_previous_velocity_ = true;
  previous_motor_velocity_rad_s_ = velocity_rad_s;
  previous_velocity_cycle_ = b.cycle();
  return had_previous && std::fabs(acceleration_rad_s2) <= kQuasiStaticMotorAccelerationRadPerS2 &&
         written_this_cycle(b, FieldId::motor_current) && written_this_cycle(b, FieldId::spring_deflection);
}

void SpringConstantEstimator::update() {
  if (!initialised_) {
    rls_.reset(boardGet(FieldId::spring_constant_nominal));
    initialised_ = true;
  }
  if (quasi_static_sample()) {
    const float spring_torque_nm =
        boardGet(FieldId::motor_current) * boardGet(FieldId::motor_torque_constant) * boardGet(FieldId::gear_ratio);
    rls_.update(boardGet(FieldId::spring_deflection), spring_torque_nm);
  }
  const board::FieldInfo& estimate = board::info(FieldId::spring_constant_estimate);
  boardSet(FieldId::spring_constant_estimate,
           std::clamp(static_cast<float>(rls_.spring_constant()), estimate.min, estimate.max));
  boardSet(FieldId::spring_constant_confidence, static_cast<float>(rls_.confidence()));
}

}  // namespace joint
