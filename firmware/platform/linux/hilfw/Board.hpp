// hilfw::run_board: a board's whole firmware for a Linux target on SocketCAN, for a main() that
// holds only what is the board's own. A board supplies
//   - Components: its component set, constructed as Components(board, registers, dt_s) (the
//     message board, the driver registers, the control period in seconds), with
//     `bool add_to(core::Scheduler&)` adding every component (false: one came too late);
//   - Registers: its driver registers (default hilfw::HilRegisters, HilRegisters.hpp), default
//     constructible, with write_input(board::HilInputId, std::int32_t) and
//     read_output(board::HilOutputId) -> std::int32_t for the node's raw HIL I/O, and optionally
//     heartbeat_status(std::uint8_t lost_entries, bool event) for the heartbeat consumer's news
//     (platform/common/NodeOnRegisters.hpp);
//   - a BoardInfo: what --help says, and where the rogue-write fault injection aims.
// run_board does the rest (BoardRuntime.cpp): the command line (--help lists it), the lockstep
// and free-running loops, the CANopen node with LSS (its id store, --node-id 0xFF), parameter
// storage (--params), program download and the exec of the downloaded image, the field recorder,
// the rogue-write fault injection, the table's fault_flags bits as EMCY frames (when it has
// them), NMT reset node (a fresh application in place), a clean stop on SIGINT/SIGTERM and the
// counters line at exit. docs/firmware-board.md walks through a complete board.
//
//   int main(int argc, char** argv) {
//     return hilfw::run_board<LampComponents>(argc, argv, {.description = "Firmware of the lamp"});
//   }
#pragma once

#include <concepts>
#include <cstdint>
#include <optional>
#include <string_view>

#include "HilRegisters.hpp"
#include "NodeOnBoard.hpp"
#include "NodeOnRegisters.hpp"
#include "board/fields.hpp"
#include "canopen/Interfaces.hpp"
#include "core/MessageBoard.hpp"
#include "core/Scheduler.hpp"

namespace hilfw {

// The board's part of the firmware's text and fault injection.
struct BoardInfo {
  std::string_view description;  // --help's first words: "Firmware of ..."
  // The field --inject-rogue-write-at-cycle writes without owning it (a field a component
  // owns); std::nullopt: the board offers no such injection and the option is refused.
  std::optional<board::FieldId> rogue_target = std::nullopt;
  float rogue_value = 0.875F;  // the value it writes: one the owner never leaves at rest
  std::string_view program = {};  // the name in --help and messages; empty: argv[0]'s file name
};

// What run_board asks of a board's registers and components (the header's comment).
template <class Registers>
concept BoardRegisters =
    std::default_initializable<Registers> &&
    requires(Registers& registers, board::HilInputId input, board::HilOutputId output, std::int32_t raw) {
      registers.write_input(input, raw);
      { registers.read_output(output) } -> std::convertible_to<std::int32_t>;
    };

template <class Components, class Registers>
concept BoardComponents = std::constructible_from<Components, core::MessageBoard&, Registers&, float> &&
                          requires(Components& components, core::Scheduler& scheduler) {
                            { components.add_to(scheduler) } -> std::same_as<bool>;
                          };

namespace detail {

// The board's application as the runtime sees it: everything NMT reset node rebuilds.
class BoardSlot {
 public:
  // A fresh application (board, scheduler, bus writer, registers, components) in place of the
  // old one: after it every object the firmware does not store is at its power-on value.
  virtual void build(float dt_s) = 0;
  virtual core::MessageBoard& board() = 0;
  virtual core::Scheduler& scheduler() = 0;
  // The bus writer and the board's components, added to scheduler(); false: one came too late.
  virtual bool add_components() = 0;
  virtual co::FieldAccess& field_access() = 0;
  virtual co::HilIo& hil_io() = 0;
  virtual co::HeartbeatListener& heartbeat_listener() = 0;

 protected:
  ~BoardSlot() = default;
};

// The runtime (BoardRuntime.cpp): parses the command line, runs the board, returns main()'s
// exit code (or execs a downloaded image).
int run_board(int argc, char** argv, const BoardInfo& info, BoardSlot& slot);

template <class Components, class Registers>
class TypedBoardSlot final : public BoardSlot {
 public:
  void build(float dt_s) override {
    app_.reset();
    app_.emplace(dt_s);
  }
  core::MessageBoard& board() override { return app_->board; }
  core::Scheduler& scheduler() override { return app_->scheduler; }
  bool add_components() override {
    return app_->scheduler.add(app_->bus_writer) && app_->components.add_to(app_->scheduler);
  }
  co::FieldAccess& field_access() override { return field_access_; }
  co::HilIo& hil_io() override { return hil_io_; }
  co::HeartbeatListener& heartbeat_listener() override { return heartbeat_; }

 private:
  // Built in place: none of its members moves (components keep references to the others).
  struct Application {
    explicit Application(float dt_s) : components{board, registers, dt_s} {}
    Application(const Application&) = delete;
    Application& operator=(const Application&) = delete;

    core::MessageBoard board;
    core::Scheduler scheduler{board};
    platform::BusWriter bus_writer{board};
    Registers registers;
    Components components;
  };

  std::optional<Application> app_;
  platform::BoardFieldAccess<Application> field_access_{app_};
  platform::HilIoOnRegisters<Application> hil_io_{app_};
  platform::HeartbeatOnRegisters<Application> heartbeat_{app_};
};

}  // namespace detail

// The board's firmware: main()'s whole body. The exit codes: 0 clean stop (or --help),
// 1 start-up failure (bus, schedule), 2 bad command line.
template <class Components, class Registers = HilRegisters>
  requires BoardRegisters<Registers> && BoardComponents<Components, Registers>
int run_board(int argc, char** argv, const BoardInfo& info) {
  static detail::TypedBoardSlot<Components, Registers> slot;  // static: a board is not stack-sized
  return detail::run_board(argc, argv, info, slot);
}

}  // namespace hilfw
