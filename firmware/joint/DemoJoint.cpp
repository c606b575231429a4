#include "joint/DemoJoint.hpp"

#include <initializer_list>

namespace joint {

using board::FieldId;

DemoJoint::DemoJoint(core::MessageBoard& board, const JointDrivers& drivers, float dt_s)
    : motor_encoder_{board, "motor_encoder", drivers.motor_encoder, FieldId::motor_position,
                     FieldId::motor_encoder_raw, FieldId::encoder_counts_per_rev},
      output_encoder_{board, "output_encoder", drivers.output_encoder, FieldId::output_position,
                      FieldId::output_encoder_raw, FieldId::output_encoder_counts_per_rev},
      thermistor_{board, drivers.thermistor_adc},
      motor_current_{board, drivers.motor_current},
      heartbeat_{board, drivers.heartbeat},
      motor_velocity_{board, "motor_velocity", FieldId::motor_encoder_raw, FieldId::encoder_counts_per_rev,
                      FieldId::motor_velocity, dt_s},
      output_velocity_{board, "output_velocity", FieldId::output_encoder_raw, FieldId::output_encoder_counts_per_rev,
                       FieldId::output_velocity, dt_s},
      spring_deflection_{board},
      joint_torque_{board},
      winding_temperature_{board},
      thermal_protection_{board},
      command_watchdog_{board},
      cia402_drive_{board, dt_s},
      fault_manager_{board},
      velocity_controller_{board, dt_s},
      torque_controller_{board, dt_s},
      drive_arbiter_{board},
      spring_constant_estimator_{board, dt_s},
      led_pattern_{board},
      motor_{board, drivers.motor_duty},
      status_led_{board, drivers.status_led} {}

bool DemoJoint::add_to(core::Scheduler& scheduler) {
  for (core::MessageBoardUser* component : std::initializer_list<core::MessageBoardUser*>{
           &motor_encoder_, &output_encoder_, &thermistor_, &motor_current_, &heartbeat_, &motor_velocity_, &output_velocity_,
           &spring_deflection_, &joint_torque_, &winding_temperature_, &thermal_protection_, &command_watchdog_,
           &cia402_drive_, &fault_manager_, &velocity_controller_, &torque_controller_, &drive_arbiter_,
           &spring_constant_estimator_, &led_pattern_, &motor_, &status_led_}) {
    if (!scheduler.add(*component)) {
      return false;
    }
  }
  return true;
}

}  // namespace joint
