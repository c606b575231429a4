// The CANopen node's views of the head module's application (beside NodeOnBoard.hpp's): its raw
// HIL I/O goes through the head's driver registers, never the board (the interrupt policy).
// `Application` has `registers` (head::HeadRegisters) besides NodeOnBoard.hpp's members.
#pragma once

#include <cstdint>
#include <optional>

#include "NodeOnBoard.hpp"
#include "canopen/Interfaces.hpp"
#include "head/drivers/HeadRegisters.hpp"

namespace platform {

template <class Application>
class HilIoOnRegisters final : public co::HilIo {
 public:
  explicit HilIoOnRegisters(std::optional<Application>& app) : app_{app} {}
  void write_input(board::HilInputId id, std::int32_t raw) override { app_->registers.write_input(id, raw); }
  std::int32_t read_output(board::HilOutputId id) override { return app_->registers.read_output(id); }

 private:
  std::optional<Application>& app_;
};

// The head has no component that reacts to a lost master: the node's own EMCY (heartbeat_error,
// naming the lost node) is its whole answer, so the consumer's news goes nowhere else.
template <class Application>
class HeartbeatOnRegisters final : public co::HeartbeatListener {
 public:
  explicit HeartbeatOnRegisters(std::optional<Application>&) {}
  void heartbeat_status(std::uint8_t, bool) override {}
};

}  // namespace platform
