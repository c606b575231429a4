// The CANopen node's views of the demo joint's application, for every platform's main (Linux and
// Cortex-M): the board-independent ones are NodeOnBoard.hpp's; here the joint's raw HIL I/O and
// heartbeat news, which go through the joint's driver registers, never the board (the interrupt
// policy). `Application` has `registers` (joint::HilRegisters) besides NodeOnBoard.hpp's members.
#pragma once

#include <cstdint>
#include <optional>

#include "board/fields.hpp"
#include "canopen/Emcy.hpp"
#include "canopen/Interfaces.hpp"
#include "canopen/Node.hpp"
#include "core/MessageBoard.hpp"
#include "core/MessageBoardUser.hpp"
#include "joint/drivers/HilRegisters.hpp"
#include "NodeOnBoard.hpp"

namespace platform {

template <class Application>
class HilIoOnRegisters final : public co::HilIo {
 public:
  explicit HilIoOnRegisters(std::optional<Application>& app) : app_{app} {}
  void write_input(board::HilInputId id, std::int32_t raw) override {
    joint::HilRegisters& registers = app_->registers;
    switch (id) {
      case board::HilInputId::motor_encoder_counts:
        registers.write_motor_encoder(static_cast<std::uint16_t>(raw));
        break;
      case board::HilInputId::output_encoder_counts:
        registers.write_output_encoder(static_cast<std::uint16_t>(raw));
        break;
      case board::HilInputId::thermistor_adc:
        registers.write_thermistor_adc(static_cast<std::uint16_t>(raw));
        break;
      case board::HilInputId::motor_current_adc:
        registers.write_motor_current(static_cast<std::int16_t>(raw));
        break;
      case board::HilInputId::kCount:
        break;
    }
  }
  std::int32_t read_output(board::HilOutputId id) override {
    switch (id) {
      case board::HilOutputId::motor_duty: return app_->registers.motor_duty_raw();
      case board::HilOutputId::led_pattern: return app_->registers.led_pattern_raw();
      case board::HilOutputId::kCount: break;
    }
    return 0;
  }

 private:
  std::optional<Application>& app_;
};

// The node's heartbeat consumer (0x1016) news into the joint's register; the HeartbeatSensor
// drains it in its update().
template <class Application>
class HeartbeatOnRegisters final : public co::HeartbeatListener {
 public:
  explicit HeartbeatOnRegisters(std::optional<Application>& app) : app_{app} {}
  void heartbeat_status(std::uint8_t lost_entries, bool event) override {
    app_->registers.write_heartbeat_status(lost_entries, event);
  }

 private:
  std::optional<Application>& app_;
};

}  // namespace platform
