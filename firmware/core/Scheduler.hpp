// Orders the components' update() calls from their declarations, and runs
// them once per cycle.
//
// Order: by kind (sensors, virtual sensors, modules, actuators), then within a
// kind topologically, so a component runs after the writers of the fields it
// reads this cycle; ties keep the order of add(). start() checks the
// declarations and fails with a sentence naming components and fields:
//   - two writers of one field; a Sensor reading a non-Parameter field; an
//     Actuator writing; a component writing a field of another kind;
//   - a read of a field written by a later kind, unless declared last-cycle;
//   - a cycle within a kind, spelled out writer -> field -> reader -> ... .
//
// Start-up allocates (vectors, strings); run_cycle() does not.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "core/MessageBoard.hpp"
#include "core/MessageBoardUser.hpp"
#include "core/StartupStatus.hpp"

namespace core {

// Where print_schedule() writes its text, a piece at a time.
using TextSink = void (*)(void* context, std::string_view text);

class Scheduler {
 public:
  explicit Scheduler(MessageBoard& board) : board_{board} {}
  Scheduler(const Scheduler&) = delete;
  Scheduler& operator=(const Scheduler&) = delete;

  // Registers a component, scheduled or (ComponentKind::External) not. The
  // component must outlive the scheduler. Returns false, and registers
  // nothing, once start() has succeeded.
  bool add(MessageBoardUser& component);

  // Checks all declarations, registers the owners of every declared write
  // on the board, and computes the update order. On failure nothing runs and
  // the board keeps no ownership from this call.
  StartupStatus start();
  bool started() const { return started_; }

  // board.begin_cycle(cycle), then every scheduled update() in order.
  // Runs nothing before a successful start().
  void run_cycle(std::uint32_t cycle) {
    board_.begin_cycle(cycle);
    for (MessageBoardUser* component : order_) {
      component->update();
    }
  }

  // The scheduled components in update order (empty before start()).
  std::span<MessageBoardUser* const> order() const { return order_; }
  // The components that are not scheduled (external writers), in add() order.
  std::span<MessageBoardUser* const> external_writers() const { return external_; }

  // The schedule, one component per entry with its writes and reads; reads
  // are marked "(last cycle)" or "(no writer)" where that applies.
  std::string schedule_text() const;
  void print_schedule(TextSink sink, void* context) const;

 private:
  MessageBoard& board_;
  std::vector<MessageBoardUser*> added_;
  std::vector<MessageBoardUser*> order_;
  std::vector<MessageBoardUser*> external_;
  bool started_ = false;
};

}  // namespace core
