// The joint's CiA 402 drive face: the state machine (controlword 0x6040 -> statusword 0x6041),
// the modes of operation (0x6060 -> 0x6061) and the actual values (0x6064, 0x606C, 0x6077) on
// the joint's own controllers and protection. Writes what the controllers follow: drive_mode
// and the drive_*_reference fields.
//
// Two faces, one drive: while no CiA 402 mode is selected (0x6060 = 0, the default) control_mode
// and the setpoints pass through unchanged, whatever the state machine's state, so a master of
// the joint's own objects sees the joint as before. Once a 402 mode runs, the drive moves only
// in operation enabled (and ramps down in quick stop active).
//
// Protection: a latched fault (safe_state, last cycle's: the fault manager reads this module's
// drive_fault_reset) is fault reaction active, then fault. 0x605E = 0: the reaction is the
// joint's safe state (zero duty at once), fault after one cycle. 0x605E = 1 or 2 in a 402 mode
// that moves the joint, on faults that leave the sensors (FaultBits.hpp): the drive ramps its
// velocity demand to rest on 0x6084 or 0x6085 from the velocity the joint has, then fault (once
// the demand is at rest, whether or not the joint is: the reaction lasts the ramp); it
// sets drive_fault_ramp meanwhile, which lets the controllers, the arbiter and the motor follow
// through the safe state (from the fault's first cycle on, which still runs the mode's command).
// A fault without sensors during the ramp cuts the duty at once and ends it. Fault reset
// (controlword bit 7 rising) asks the fault manager to clear the latch (drive_fault_reset = 1
// for a cycle) by its rules: a cause still present latches again and the drive stays in fault.
//
// Mistakes a master makes get the standard answers: a command the current state has no
// transition for (enable operation in switch on disabled) is not taken; a mode this drive does
// not offer (0x6502) is not taken, 0x6061 keeps the mode; targets before operation enabled move
// nothing (the profile modes start from rest when enabled, profile position only at a new
// set-point); a mode switch with halt set switches, and the new mode stays halted.
#pragma once

#include <cstdint>

#include "board/cia402.hpp"
#include "core/MessageBoardUser.hpp"
#include "joint/ControlMode.hpp"

namespace joint {

using Cia402Mode = board::Cia402Mode;

// 0x6502: bit n-1 for each mode n the drive offers (every one of board.toml's cia402_mode but 0).
constexpr std::uint32_t supported_drive_modes() {
  std::uint32_t bits = 0;
  for (const Cia402Mode mode : board::kCia402ModeValues) {
    const auto value = static_cast<std::uint32_t>(mode);
    if (value != 0) bits |= 1u << (value - 1u);
  }
  return bits;
}

// What a controlword commands (CiA 402, the device control commands), from bits 0..3 and 7.
enum class DriveCommand : std::uint8_t { None, Shutdown, SwitchOn, EnableOperation, DisableVoltage, QuickStop };
DriveCommand decode_controlword(std::uint16_t controlword);

// One step of the state machine for a command, outside the fault states: the state the command
// leads to (the same state when it has no transition there). Leaving quick stop active also
// depends on 0x605A: Cia402Drive decides that.
cia402::State next_state(cia402::State state, DriveCommand command);

class Cia402Drive final : public core::Module {
 public:
  // dt_s: the control cycle period.
  Cia402Drive(core::MessageBoard& board, float dt_s);

  void update() override;

 private:
  enum class Homing : std::uint8_t { Idle, Running, Attained, Interrupted, Error };
  struct Command {
    ControlMode mode;
    float velocity_rad_s;
    float torque_nm;
    float position_rad;
  };

  void update_state(std::uint16_t controlword, bool safe, std::uint32_t fault_flags, float gearbox_rad_s);
  void select_mode(float requested, float gearbox_rad, float gearbox_rad_s);
  Command legacy() const;
  Command run_mode(std::uint16_t controlword, bool rising_set_point, float gearbox_rad, float gearbox_rad_s);
  Command quick_stop(float gearbox_rad_s);
  Command fault_reaction();
  bool at_rest(float gearbox_rad_s) const;  // the demand at 0 and the joint within 0x606D
  float ramp(float from, float to, float acceleration) const;
  float velocity_limit() const;  // 0x607F and 0x6080, the smaller [rad/s]
  float mrad_to_gearbox_rad(float mrad) const;
  // A position target clamped to the software position limit (0x607D; a min above the max
  // leaves it unlimited); notes in position_limited_ whether it was.
  float limit_position(float gearbox_rad);
  float rated_torque_nm() const;
  std::uint16_t mode_bits(float gearbox_rad, float gearbox_rad_s) const;

  float dt_s_;
  cia402::State state_ = cia402::State::NotReadyToSwitchOn;
  Cia402Mode mode_ = Cia402Mode::NoMode;
  std::uint16_t previous_controlword_ = 0;
  bool reset_pending_ = false;
  bool halted_ = false;
  bool fault_ramp_ = false;  // fault reaction active ramps (0x605E = 1, 2) rather than disables
  double zero_rad_ = 0.0;        // gearbox-side angle where position_actual_value = home_offset
  float velocity_rad_s_ = 0.0F;  // the ramped velocity demand (profile modes, halt, quick stop)
  float position_rad_ = 0.0F;    // the position demand (profile position, homing, halted csp)
  float pp_target_rad_ = 0.0F;
  bool pp_moving_ = false;
  bool position_limited_ = false;  // the position mode's target was clamped to 0x607D
  bool set_point_acknowledged_ = false;
  Homing homing_ = Homing::Idle;
};

}  // namespace joint
