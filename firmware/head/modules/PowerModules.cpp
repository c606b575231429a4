#include "head/modules/PowerModules.hpp"

#include <cstdint>

namespace head {

using board::FieldId;

bool rail_closed(float rail_enable, float fault_flags) {
  const auto flags = static_cast<std::uint32_t>(fault_flags);
  return rail_enable >= 0.5F && (flags & board::mask(board::FaultFlagsBit::RailOverCurrent)) == 0;
}

float clamp_duty(float duty) {
  if (!(duty > 0.0F)) return 0.0F;  // also NaN
  return duty < 1.0F ? duty : 1.0F;
}

RailSwitch::RailSwitch(core::MessageBoard& board)
    : Module(board, "rail_switch",
             {.writes = {FieldId::rail_on}, .reads = {FieldId::rail_enable, FieldId::fault_flags}}) {}

void RailSwitch::update() {
  boardSet(FieldId::rail_on, rail_closed(boardGet(FieldId::rail_enable), boardGet(FieldId::fault_flags)) ? 1.0F : 0.0F);
}

LedMixer::LedMixer(core::MessageBoard& board)
    : Module(board, "led_mixer",
             {.writes = {FieldId::led_red_duty, FieldId::led_green_duty, FieldId::led_blue_duty},
              .reads = {FieldId::led_red, FieldId::led_green, FieldId::led_blue, FieldId::rail_on}}) {}

void LedMixer::update() {
  const float powered = boardGet(FieldId::rail_on) != 0.0F ? 1.0F : 0.0F;
  boardSet(FieldId::led_red_duty, powered * clamp_duty(boardGet(FieldId::led_red)));
  boardSet(FieldId::led_green_duty, powered * clamp_duty(boardGet(FieldId::led_green)));
  boardSet(FieldId::led_blue_duty, powered * clamp_duty(boardGet(FieldId::led_blue)));
}

}  // namespace head
