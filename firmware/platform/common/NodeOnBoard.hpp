// The CANopen node's views of any board's application, for every platform's main: the node reads
// the board and writes only the bus-writable fields, through the bus writer. `Application` has
// `board` (core::MessageBoard) and `bus_writer` (BusWriter); each view follows the application in
// its std::optional, which NMT reset node rebuilds. The views of a board's registers (raw HIL I/O,
// heartbeat news) are NodeOnRegisters.hpp's.
#pragma once

#include <optional>

#include "board/fields.hpp"
#include "canopen/Emcy.hpp"
#include "canopen/Interfaces.hpp"
#include "canopen/Node.hpp"
#include "core/MessageBoard.hpp"
#include "core/MessageBoardUser.hpp"

namespace platform {

// The node's write access to the board: an external writer of the bus-writable fields.
class BusWriter final : public core::ExternalWriter {
 public:
  explicit BusWriter(core::MessageBoard& board)
      : ExternalWriter(board, "canopen_node", {.writes = core::kBusWritableFields}) {}

  core::SetResult write(board::FieldId id, float value) { return boardSet(id, value); }
};

// The board's refused writes become EMCY frames naming the field (board.toml's [[emcy]]
// ownership_violation); `context` is the co::Node.
inline void report_ownership_violation(void* context, const core::WriteViolation& violation) {
  static_cast<co::Node*>(context)->report_emcy(co::emcy::ownership_violation(violation.field));
}

template <class Application>
class BoardFieldAccess final : public co::FieldAccess {
 public:
  explicit BoardFieldAccess(std::optional<Application>& app) : app_{app} {}
  float read(board::FieldId id) override { return app_->board.get(id); }
  co::WriteResult write(board::FieldId id, float value) override {
    return app_->bus_writer.write(id, value) == core::SetResult::Ok ? co::WriteResult::Accepted
                                                                     : co::WriteResult::Refused;
  }

 private:
  std::optional<Application>& app_;
};

}  // namespace platform
