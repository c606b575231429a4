// The rail switch and the LED mixer, the head's two behaviour modules after the fault monitor.
//   RailSwitch: rail_on = rail_enable and no latched rail over-current (a trip holds the rail
//     open until fault_clear, however rail_enable changes).
//   LedMixer:   led_*_duty = the led_* command (clamped to 0..1, NaN as 0) while the rail is on,
//     else 0: the LED hangs on the rail.
#pragma once

#include "core/MessageBoardUser.hpp"

namespace head {

// rail_on from rail_enable and the latched fault flags.
bool rail_closed(float rail_enable, float fault_flags);

// A commanded duty made safe for the PWM: 0..1, NaN -> 0.
float clamp_duty(float duty);

class RailSwitch final : public core::Module {
 public:
  explicit RailSwitch(core::MessageBoard& board);
  void update() override;
};

class LedMixer final : public core::Module {
 public:
  explicit LedMixer(core::MessageBoard& board);
  void update() override;
};

}  // namespace head
