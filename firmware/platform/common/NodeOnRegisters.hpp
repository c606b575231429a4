// The CANopen node's views of a board's driver registers, for every platform's main (beside
// NodeOnBoard.hpp's): raw HIL I/O and the heartbeat consumer's news go through the registers,
// never the board (the interrupt policy). `Application` has `registers` besides NodeOnBoard.hpp's
// members; the registers have
//   void write_input(board::HilInputId, std::int32_t raw)     the receive path's raw input
//   std::int32_t read_output(board::HilOutputId)              the transmit path's raw output
// and, when a component reacts to a lost heartbeat,
//   void heartbeat_status(std::uint8_t lost_entries, bool event)
// Without it the node's own EMCY (heartbeat_error, naming the lost node) is the board's answer.
#pragma once

#include <cstdint>
#include <optional>

#include "NodeOnBoard.hpp"
#include "board/fields.hpp"
#include "canopen/Interfaces.hpp"

namespace platform {

template <class Registers>
concept HeartbeatRegisters = requires(Registers& registers, std::uint8_t lost, bool event) {
  registers.heartbeat_status(lost, event);
};

template <class Application>
class HilIoOnRegisters final : public co::HilIo {
 public:
  explicit HilIoOnRegisters(std::optional<Application>& app) : app_{app} {}
  void write_input(board::HilInputId id, std::int32_t raw) override { app_->registers.write_input(id, raw); }
  std::int32_t read_output(board::HilOutputId id) override { return app_->registers.read_output(id); }

 private:
  std::optional<Application>& app_;
};

template <class Application>
class HeartbeatOnRegisters final : public co::HeartbeatListener {
 public:
  explicit HeartbeatOnRegisters(std::optional<Application>& app) : app_{app} {}
  void heartbeat_status(std::uint8_t lost_entries, bool event) override {
    if constexpr (HeartbeatRegisters<decltype(app_->registers)>) app_->registers.heartbeat_status(lost_entries, event);
  }

 private:
  std::optional<Application>& app_;
};

}  // namespace platform
