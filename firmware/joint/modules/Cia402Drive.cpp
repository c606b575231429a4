#include "joint/modules/Cia402Drive.hpp"

#include <algorithm>
#include <cmath>

#include "joint/BoardReads.hpp"
#include "joint/FaultBits.hpp"

namespace joint {

using board::FieldId;
using cia402::ControlBit;
using cia402::State;
using cia402::StatusBit;

namespace {

constexpr float kMilli = 1.0e-3F;

bool has(std::uint16_t word, ControlBit b) { return (word & cia402::bit(b)) != 0; }

bool offered(float requested) {
  const auto mode = board::cia402_mode_from_value(requested);
  return mode.has_value();
}

// Quick stop options 5 and 6 stay in quick stop active once stopped; 0 coasts.
constexpr bool stays_in_quick_stop(int option) { return option == 5 || option == 6; }

// Fault reaction options 1 and 2 slow down (on 0x6084, 0x6085), 0 disables at once.
constexpr bool ramps_a_fault(int option) { return option == 1 || option == 2; }

static_assert(static_cast<float>(supported_drive_modes()) == board::info(FieldId::supported_drive_modes).default_value,
              "board.toml: supported_drive_modes' default is not the bits of the cia402_mode values");
static_assert((board::kNode.device_type & 0xFFFFu) == cia402::kDeviceProfile,
              "board.toml: [node] device_type does not name CiA 402 (0x0192) for a 402 drive");

}  // namespace

DriveCommand decode_controlword(std::uint16_t controlword) {
  const unsigned low = controlword & 0x0Fu;
  if ((low & 0x02u) == 0) return DriveCommand::DisableVoltage;  // xxxx xx0x
  if ((low & 0x06u) == 0x02u) return DriveCommand::QuickStop;   // xxxx x01x
  if ((low & 0x07u) == 0x06u) return DriveCommand::Shutdown;    // xxxx x110
  if (low == 0x07u) return DriveCommand::SwitchOn;              // xxxx 0111 (also disable operation)
  if (low == 0x0Fu) return DriveCommand::EnableOperation;       // xxxx 1111
  return DriveCommand::None;
}

State next_state(State state, DriveCommand command) {
  switch (state) {
    case State::NotReadyToSwitchOn: return State::SwitchOnDisabled;  // transition 1, automatic
    case State::SwitchOnDisabled:
      return command == DriveCommand::Shutdown ? State::ReadyToSwitchOn : state;  // 2
    case State::ReadyToSwitchOn:
      if (command == DriveCommand::SwitchOn || command == DriveCommand::EnableOperation) return State::SwitchedOn;  // 3
      if (command == DriveCommand::DisableVoltage || command == DriveCommand::QuickStop) return State::SwitchOnDisabled;  // 7
      return state;
    case State::SwitchedOn:
      if (command == DriveCommand::EnableOperation) return State::OperationEnabled;  // 4
      if (command == DriveCommand::Shutdown) return State::ReadyToSwitchOn;          // 6
      if (command == DriveCommand::DisableVoltage || command == DriveCommand::QuickStop) return State::SwitchOnDisabled;  // 10
      return state;
    case State::OperationEnabled:
      if (command == DriveCommand::SwitchOn) return State::SwitchedOn;              // 5
      if (command == DriveCommand::Shutdown) return State::ReadyToSwitchOn;         // 8
      if (command == DriveCommand::DisableVoltage) return State::SwitchOnDisabled;  // 9
      if (command == DriveCommand::QuickStop) return State::QuickStopActive;        // 11
      return state;
    case State::QuickStopActive:
      if (command == DriveCommand::DisableVoltage) return State::SwitchOnDisabled;  // 12
      if (command == DriveCommand::EnableOperation) return State::OperationEnabled;  // 16
      return state;
    case State::FaultReactionActive:
    case State::Fault: return state;  // left by the fault rules, never by a command
  }
  return state;
}

Cia402Drive::Cia402Drive(core::MessageBoard& board, float dt_s)
    : Module(board, "cia402_drive",
             {.writes = {FieldId::statusword, FieldId::modes_of_operation_display, FieldId::position_actual_value,
                         FieldId::velocity_actual_value, FieldId::torque_actual_value, FieldId::supported_drive_modes,
                         FieldId::drive_mode, FieldId::drive_velocity_reference, FieldId::drive_torque_reference,
                         FieldId::drive_position_reference, FieldId::drive_fault_reset, FieldId::drive_fault_ramp},
              .reads = {FieldId::controlword, FieldId::modes_of_operation, FieldId::target_position,
                        FieldId::target_velocity, FieldId::target_torque, FieldId::quick_stop_option_code,
                        FieldId::fault_reaction_option_code,
                        FieldId::following_error_window, FieldId::position_window, FieldId::velocity_window,
                        FieldId::motor_rated_torque, FieldId::home_offset, FieldId::max_profile_velocity, FieldId::max_motor_speed,
                        FieldId::profile_velocity, FieldId::profile_acceleration, FieldId::profile_deceleration,
                        FieldId::quick_stop_deceleration, FieldId::homing_method, FieldId::control_mode,
                        FieldId::min_position_limit, FieldId::max_position_limit,
                        FieldId::speed_during_search_for_switch,
                        FieldId::velocity_setpoint, FieldId::torque_setpoint, FieldId::position_setpoint,
                        FieldId::motor_position, FieldId::motor_velocity, FieldId::gear_ratio, FieldId::joint_torque},
              .reads_last_cycle = {FieldId::safe_state, FieldId::fault_flags}}),
      dt_s_{dt_s} {}

float Cia402Drive::velocity_limit() const {
  return std::min(boardGet(FieldId::max_profile_velocity), boardGet(FieldId::max_motor_speed)) * kMilli;
}

float Cia402Drive::ramp(float from, float to, float acceleration) const {
  const float step = std::max(acceleration, 0.0F) * dt_s_;
  return from + std::clamp(to - from, -step, step);
}

float Cia402Drive::mrad_to_gearbox_rad(float mrad) const {
  return static_cast<float>(zero_rad_ + static_cast<double>(mrad - boardGet(FieldId::home_offset)) * kMilli);
}

float Cia402Drive::limit_position(float gearbox_rad) {
  const float low = boardGet(FieldId::min_position_limit);
  const float high = boardGet(FieldId::max_position_limit);
  if (low > high) {
    position_limited_ = false;
    return gearbox_rad;
  }
  const float limited = std::clamp(gearbox_rad, mrad_to_gearbox_rad(low), mrad_to_gearbox_rad(high));
  position_limited_ = limited != gearbox_rad;
  return limited;
}

float Cia402Drive::rated_torque_nm() const { return boardGet(FieldId::motor_rated_torque) * kMilli; }

bool Cia402Drive::at_rest(float gearbox_rad_s) const {
  return velocity_rad_s_ == 0.0F && std::fabs(gearbox_rad_s) <= boardGet(FieldId::velocity_window) * kMilli;
}

void Cia402Drive::update_state(std::uint16_t controlword, bool safe, std::uint32_t fault_flags, float gearbox_rad_s) {
  const bool fault_reset = has(controlword, ControlBit::FaultReset) && !has(previous_controlword_, ControlBit::FaultReset);
  boardSet(FieldId::drive_fault_reset, 0.0F);
  if (state_ == State::Fault) {
    if (reset_pending_) {
      reset_pending_ = false;
      if (!safe) state_ = State::SwitchOnDisabled;  // transition 15: the latch cleared
    }
    if (fault_reset) {
      boardSet(FieldId::drive_fault_reset, 1.0F);
      reset_pending_ = true;
    }
    return;
  }
  if (safe && state_ != State::FaultReactionActive) {
    // Transition 13. With 0x605E = 1 or 2 a 402 mode that moves the joint slows down first,
    // from the velocity the joint has, if every latched fault leaves the sensors to ramp on.
    const bool moving = state_ == State::OperationEnabled || state_ == State::QuickStopActive;
    fault_ramp_ = moving && mode_ != Cia402Mode::NoMode && faults_keep_the_sensors(fault_flags) &&
                  ramps_a_fault(static_cast<int>(boardGet(FieldId::fault_reaction_option_code)));
    if (fault_ramp_) velocity_rad_s_ = gearbox_rad_s;
    state_ = State::FaultReactionActive;
    return;
  }
  if (state_ == State::FaultReactionActive) {
    // Transition 14 once the reaction has taken effect: the safe state's zero duty at once, a
    // ramp once its demand is at rest (fault_reaction); a fault that leaves no sensor (the
    // safe state cut the duty already) or a latch cleared meanwhile ends the ramp.
    if (!fault_ramp_ || !safe || !faults_keep_the_sensors(fault_flags)) {
      fault_ramp_ = false;
      state_ = State::Fault;
    }
    return;
  }
  const DriveCommand command = decode_controlword(controlword);
  const State next = next_state(state_, command);
  if (state_ == State::QuickStopActive && next == State::OperationEnabled &&
      !stays_in_quick_stop(static_cast<int>(boardGet(FieldId::quick_stop_option_code)))) {
    return;  // options 0..2 leave quick stop for switch on disabled only
  }
  if (next == State::QuickStopActive && state_ != State::QuickStopActive) {
    velocity_rad_s_ = boardGet(FieldId::motor_velocity) / boardGet(FieldId::gear_ratio);
  }
  if (next == State::OperationEnabled && state_ != State::OperationEnabled && state_ != State::QuickStopActive) {
    // Enabled from rest: profile modes ramp from the velocity the joint has, and hold where it is.
    velocity_rad_s_ = 0.0F;
    position_rad_ = boardGet(FieldId::motor_position) / boardGet(FieldId::gear_ratio);
    pp_target_rad_ = position_rad_;
    pp_moving_ = false;
  }
  state_ = next;
}

void Cia402Drive::select_mode(float requested, float gearbox_rad, float gearbox_rad_s) {
  if (!offered(requested)) return;  // 0x6061 keeps the mode
  const auto mode = *board::cia402_mode_from_value(requested);
  if (mode == mode_) return;
  mode_ = mode;
  velocity_rad_s_ = gearbox_rad_s;
  position_rad_ = gearbox_rad;
  pp_target_rad_ = gearbox_rad;
  pp_moving_ = false;
  position_limited_ = false;
  homing_ = Homing::Idle;
}

Cia402Drive::Command Cia402Drive::legacy() const {
  return {control_mode_from_field(boardGet(FieldId::control_mode)), boardGet(FieldId::velocity_setpoint),
          boardGet(FieldId::torque_setpoint), boardGet(FieldId::position_setpoint)};
}

Cia402Drive::Command Cia402Drive::quick_stop(float gearbox_rad_s) {
  const int option = static_cast<int>(boardGet(FieldId::quick_stop_option_code));
  if (mode_ == Cia402Mode::NoMode) {
    // No 402 mode: nothing of the drive's to ramp down (control_mode drives the joint).
    if (!stays_in_quick_stop(option)) state_ = State::SwitchOnDisabled;
    return {ControlMode::Disabled, 0.0F, 0.0F, 0.0F};
  }
  if (option == 0) {
    state_ = State::SwitchOnDisabled;  // coast: the drive function is disabled at once
    return {ControlMode::Disabled, 0.0F, 0.0F, 0.0F};
  }
  const bool slow = option == 1 || option == 5;
  const float deceleration =
      (slow ? boardGet(FieldId::profile_deceleration) : boardGet(FieldId::quick_stop_deceleration)) * kMilli;
  velocity_rad_s_ = ramp(velocity_rad_s_, 0.0F, deceleration);
  if (at_rest(gearbox_rad_s) && !stays_in_quick_stop(option)) {
    state_ = State::SwitchOnDisabled;  // transition 12 once stopped
    return {ControlMode::Disabled, 0.0F, 0.0F, 0.0F};
  }
  return {ControlMode::Velocity, velocity_rad_s_, 0.0F, 0.0F};
}

Cia402Drive::Command Cia402Drive::fault_reaction() {
  const bool slow = static_cast<int>(boardGet(FieldId::fault_reaction_option_code)) == 1;
  const float deceleration =
      (slow ? boardGet(FieldId::profile_deceleration) : boardGet(FieldId::quick_stop_deceleration)) * kMilli;
  velocity_rad_s_ = ramp(velocity_rad_s_, 0.0F, deceleration);
  if (velocity_rad_s_ == 0.0F) {
    // Transition 14 once the demand is at rest, the drive function disabled: bounded by the
    // ramp (velocity / deceleration) whatever the joint does, unlike quick stop's wait for it.
    fault_ramp_ = false;
    state_ = State::Fault;
    return {ControlMode::Disabled, 0.0F, 0.0F, 0.0F};
  }
  return {ControlMode::Velocity, velocity_rad_s_, 0.0F, 0.0F};
}

Cia402Drive::Command Cia402Drive::run_mode(std::uint16_t controlword, bool rising_set_point, float gearbox_rad,
                                           float gearbox_rad_s) {
  const float acceleration = boardGet(FieldId::profile_acceleration) * kMilli;
  const float deceleration = boardGet(FieldId::profile_deceleration) * kMilli;
  const float max_velocity = velocity_limit();
  const float target_velocity = std::clamp(boardGet(FieldId::target_velocity) * kMilli, -max_velocity, max_velocity);
  const float target_torque = boardGet(FieldId::target_torque) * kMilli * rated_torque_nm();
  halted_ = has(controlword, ControlBit::Halt);
  switch (mode_) {
    case Cia402Mode::ProfileVelocity: {
      const float goal = halted_ ? 0.0F : target_velocity;
      const bool speeding_up = std::fabs(goal) > std::fabs(velocity_rad_s_) && goal * velocity_rad_s_ >= 0.0F;
      velocity_rad_s_ = ramp(velocity_rad_s_, goal, speeding_up ? acceleration : deceleration);
      return {ControlMode::Velocity, velocity_rad_s_, 0.0F, 0.0F};
    }
    case Cia402Mode::CyclicSynchronousVelocity:
      velocity_rad_s_ = halted_ ? ramp(velocity_rad_s_, 0.0F, deceleration) : target_velocity;
      return {ControlMode::Velocity, velocity_rad_s_, 0.0F, 0.0F};
    case Cia402Mode::ProfileTorque:
    case Cia402Mode::CyclicSynchronousTorque:
      return {ControlMode::Torque, 0.0F, halted_ ? 0.0F : target_torque, 0.0F};
    case Cia402Mode::CyclicSynchronousPosition:
      if (!halted_) position_rad_ = limit_position(mrad_to_gearbox_rad(boardGet(FieldId::target_position)));
      return {ControlMode::Position, 0.0F, 0.0F, position_rad_};
    case Cia402Mode::ProfilePosition: {
      if (!has(controlword, ControlBit::NewSetPoint)) set_point_acknowledged_ = false;
      if (rising_set_point && !halted_) {
        const float target = boardGet(FieldId::target_position);
        pp_target_rad_ = limit_position(has(controlword, ControlBit::Relative) ? pp_target_rad_ + target * kMilli
                                                                               : mrad_to_gearbox_rad(target));
        pp_moving_ = true;
        set_point_acknowledged_ = true;
      }
      const float error = halted_ ? 0.0F : pp_target_rad_ - position_rad_;
      const float cruise = std::min(boardGet(FieldId::profile_velocity) * kMilli, max_velocity);
      float goal = std::copysign(std::min(cruise, std::sqrt(2.0F * deceleration * std::fabs(error))), error);
      if (halted_ || !pp_moving_) goal = 0.0F;
      velocity_rad_s_ = ramp(velocity_rad_s_, goal, std::fabs(goal) > std::fabs(velocity_rad_s_) ? acceleration : deceleration);
      position_rad_ += velocity_rad_s_ * dt_s_;
      if (pp_moving_ && !halted_ && std::fabs(pp_target_rad_ - position_rad_) <= std::fabs(velocity_rad_s_) * dt_s_ + 1.0e-6F) {
        position_rad_ = pp_target_rad_;
        velocity_rad_s_ = 0.0F;
        pp_moving_ = false;
      }
      return {ControlMode::Position, 0.0F, 0.0F, position_rad_};
    }
    case Cia402Mode::Homing: {
      const int method = static_cast<int>(boardGet(FieldId::homing_method));
      if (rising_set_point) {
        if (method == 35 || method == 37) {
          zero_rad_ = gearbox_rad;
          homing_ = Homing::Attained;
        } else if (method == -3) {
          homing_ = Homing::Running;
          velocity_rad_s_ = 0.0F;
          position_rad_ = gearbox_rad;
        } else {
          homing_ = Homing::Error;
        }
      }
      if (homing_ == Homing::Running && halted_) homing_ = Homing::Interrupted;
      if (homing_ == Homing::Running) {
        const float speed = std::min(boardGet(FieldId::speed_during_search_for_switch) * kMilli, max_velocity);
        velocity_rad_s_ = ramp(velocity_rad_s_, -speed, acceleration);
        position_rad_ += velocity_rad_s_ * dt_s_;
        if (std::fabs(position_rad_ - gearbox_rad) > boardGet(FieldId::following_error_window) * kMilli) {
          zero_rad_ = gearbox_rad;  // the hard stop: the joint no longer follows
          homing_ = Homing::Attained;
          velocity_rad_s_ = 0.0F;
        }
        return {ControlMode::Velocity, velocity_rad_s_, 0.0F, 0.0F};
      }
      velocity_rad_s_ = ramp(velocity_rad_s_, 0.0F, deceleration);
      return {ControlMode::Velocity, velocity_rad_s_, 0.0F, 0.0F};
    }
    case Cia402Mode::NoMode: break;
  }
  (void)gearbox_rad_s;
  return legacy();
}

std::uint16_t Cia402Drive::mode_bits(float gearbox_rad, float gearbox_rad_s) const {
  if (state_ != State::OperationEnabled) return 0;
  const float velocity_window = boardGet(FieldId::velocity_window) * kMilli;
  const auto bit = [](StatusBit b, bool on) { return on ? cia402::bit(b) : std::uint16_t{0}; };
  switch (mode_) {
    case Cia402Mode::ProfileVelocity: {
      const float goal = halted_ ? 0.0F : boardGet(FieldId::target_velocity) * kMilli;
      return bit(StatusBit::TargetReached, std::fabs(gearbox_rad_s - goal) <= velocity_window) |
             bit(StatusBit::OperationModeSpecific12, std::fabs(gearbox_rad_s) <= velocity_window);
    }
    case Cia402Mode::ProfilePosition: {
      const float window = boardGet(FieldId::position_window) * kMilli;
      const bool reached = !pp_moving_ && std::fabs(pp_target_rad_ - gearbox_rad) <= window;
      return bit(StatusBit::TargetReached, reached || (halted_ && std::fabs(gearbox_rad_s) <= velocity_window)) |
             bit(StatusBit::OperationModeSpecific12, set_point_acknowledged_) |
             bit(StatusBit::OperationModeSpecific13,
                 std::fabs(position_rad_ - gearbox_rad) > boardGet(FieldId::following_error_window) * kMilli);
    }
    case Cia402Mode::Homing:
      switch (homing_) {
        case Homing::Idle:
        case Homing::Running: return 0;
        case Homing::Attained:
          return bit(StatusBit::OperationModeSpecific12, true) |
                 bit(StatusBit::TargetReached, std::fabs(gearbox_rad_s) <= velocity_window);
        case Homing::Interrupted: return bit(StatusBit::TargetReached, true);
        case Homing::Error:
          return bit(StatusBit::OperationModeSpecific13, true) |
                 bit(StatusBit::TargetReached, std::fabs(gearbox_rad_s) <= velocity_window);
      }
      return 0;
    case Cia402Mode::CyclicSynchronousPosition:
    case Cia402Mode::CyclicSynchronousVelocity:
    case Cia402Mode::CyclicSynchronousTorque:
      // Bit 12: the drive follows the target; bit 10 stays 0 (no target reached in cyclic modes).
      return bit(StatusBit::OperationModeSpecific12, !halted_);
    case Cia402Mode::ProfileTorque:
      return bit(StatusBit::TargetReached, halted_);
    case Cia402Mode::NoMode: break;
  }
  return 0;
}

void Cia402Drive::update() {
  const auto controlword = static_cast<std::uint16_t>(boardGet(FieldId::controlword));
  const bool safe = boardGet(FieldId::safe_state) != 0.0F;
  const auto fault_flags = static_cast<std::uint32_t>(boardGet(FieldId::fault_flags));
  const float gear_ratio = boardGet(FieldId::gear_ratio);
  const float gearbox_rad = boardGet(FieldId::motor_position) / gear_ratio;
  const float gearbox_rad_s = boardGet(FieldId::motor_velocity) / gear_ratio;
  const bool rising_set_point =
      has(controlword, ControlBit::NewSetPoint) && !has(previous_controlword_, ControlBit::NewSetPoint);

  const State before = state_;
  update_state(controlword, safe, fault_flags, gearbox_rad_s);
  select_mode(boardGet(FieldId::modes_of_operation), gearbox_rad, gearbox_rad_s);

  Command command{ControlMode::Disabled, 0.0F, 0.0F, 0.0F};
  if (state_ == State::QuickStopActive && before != State::QuickStopActive) {
    // Shown for a cycle at least; the ramp starts from the velocity the joint has.
    command = {ControlMode::Velocity, velocity_rad_s_, 0.0F, 0.0F};
  } else if (state_ == State::QuickStopActive) {
    command = quick_stop(gearbox_rad_s);
  } else if (state_ == State::FaultReactionActive && fault_ramp_) {
    command = fault_reaction();
  } else if (state_ == State::OperationEnabled && mode_ != Cia402Mode::NoMode) {
    command = run_mode(controlword, rising_set_point, gearbox_rad, gearbox_rad_s);
  }
  if (mode_ == Cia402Mode::NoMode) command = legacy();  // the state machine runs, the joint's own commands drive
  previous_controlword_ = controlword;

  std::uint16_t status = static_cast<std::uint16_t>(state_) | cia402::bit(StatusBit::Remote);
  if (state_ != State::SwitchOnDisabled && state_ != State::NotReadyToSwitchOn && state_ != State::Fault) {
    status |= cia402::bit(StatusBit::VoltageEnabled);
  }
  status |= mode_bits(gearbox_rad, gearbox_rad_s);
  const bool velocity_mode = mode_ == Cia402Mode::ProfileVelocity || mode_ == Cia402Mode::CyclicSynchronousVelocity;
  if (state_ == State::OperationEnabled && velocity_mode &&
      std::fabs(boardGet(FieldId::target_velocity) * kMilli) > velocity_limit()) {
    status |= cia402::bit(StatusBit::InternalLimitActive);  // the target is beyond 0x607F or 0x6080
  }
  const bool position_mode = mode_ == Cia402Mode::ProfilePosition || mode_ == Cia402Mode::CyclicSynchronousPosition;
  if (state_ == State::OperationEnabled && position_mode && position_limited_) {
    status |= cia402::bit(StatusBit::InternalLimitActive);  // the target was clamped to 0x607D
  }
  boardSet(FieldId::statusword, status);
  boardSet(FieldId::modes_of_operation_display, static_cast<float>(static_cast<int>(mode_)));
  const double actual_mrad = (static_cast<double>(gearbox_rad) - zero_rad_) / kMilli + boardGet(FieldId::home_offset);
  const auto clamp_to = [](double value, FieldId id) {
    return static_cast<float>(std::clamp(std::round(value), static_cast<double>(board::info(id).min),
                                         static_cast<double>(board::info(id).max)));
  };
  boardSet(FieldId::position_actual_value, clamp_to(actual_mrad, FieldId::position_actual_value));
  boardSet(FieldId::velocity_actual_value, clamp_to(gearbox_rad_s / kMilli, FieldId::velocity_actual_value));
  boardSet(FieldId::torque_actual_value,
           clamp_to(boardGet(FieldId::joint_torque) / rated_torque_nm() * 1000.0F, FieldId::torque_actual_value));
  boardSet(FieldId::supported_drive_modes, static_cast<float>(supported_drive_modes()));
  const auto limit = [](float value, FieldId id) { return std::clamp(value, board::info(id).min, board::info(id).max); };
  // Armed while a 402 mode moves the joint, so a fault's first cycle (read here a cycle late)
  // keeps the duty the mode asked for; the drive's later cycles then ramp or disable.
  const bool moving = state_ == State::OperationEnabled || state_ == State::QuickStopActive;
  const bool ramps = ramps_a_fault(static_cast<int>(boardGet(FieldId::fault_reaction_option_code)));
  const bool ramp_armed =
      mode_ != Cia402Mode::NoMode && ((moving && ramps) || (state_ == State::FaultReactionActive && fault_ramp_));
  boardSet(FieldId::drive_fault_ramp, ramp_armed ? 1.0F : 0.0F);
  boardSet(FieldId::drive_mode, board::to_value(command.mode));
  boardSet(FieldId::drive_velocity_reference, limit(command.velocity_rad_s, FieldId::drive_velocity_reference));
  boardSet(FieldId::drive_torque_reference, limit(command.torque_nm, FieldId::drive_torque_reference));
  boardSet(FieldId::drive_position_reference, limit(command.position_rad, FieldId::drive_position_reference));
}

}  // namespace joint
