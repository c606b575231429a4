// Test-only stand-ins for the parts of a running firmware around the
// component under test: the CANopen node (bus writes between cycles) and
// upstream components (writes inside a cycle, in their update()).
#pragma once

#include <array>
#include <optional>
#include <string_view>

#include "core/FieldSet.hpp"
#include "core/MessageBoard.hpp"
#include "core/MessageBoardUser.hpp"

namespace joint::testing {

// The control period the tests step components at (1 kHz).
inline constexpr float kDtS = 0.001F;

// Owns every bus-writable field, like the CANopen node. Call write() between
// run_cycle() calls, as frames arrive between cycles.
class BusStandIn final : public core::ExternalWriter {
 public:
  explicit BusStandIn(core::MessageBoard& board)
      : ExternalWriter(board, "bus_stand_in", {.writes = core::kBusWritableFields}) {}
  core::SetResult write(board::FieldId id, float value) { return boardSet(id, value); }
};

// A component of kind `Kind` (core::Sensor, core::VirtualSensor, core::Module)
// that writes the given fields in its update(): every cycle with hold(), in the
// next cycle only with once(); stop() ends a hold.
template <typename Kind>
class FieldSource final : public Kind {
 public:
  FieldSource(core::MessageBoard& board, std::string_view name, core::FieldSet writes)
      : Kind(board, name, {.writes = writes}) {}

  void hold(board::FieldId id, float value) { values_[core::field_index(id)] = Pending{value, true}; }
  void once(board::FieldId id, float value) { values_[core::field_index(id)] = Pending{value, false}; }
  void stop(board::FieldId id) { values_[core::field_index(id)].reset(); }

  void update() override {
    for (std::size_t i = 0; i < values_.size(); ++i) {
      if (values_[i]) {
        this->boardSet(static_cast<board::FieldId>(i), values_[i]->value);
        if (!values_[i]->every_cycle) {
          values_[i].reset();
        }
      }
    }
  }

 private:
  struct Pending {
    float value;
    bool every_cycle;
  };
  std::array<std::optional<Pending>, board::kFieldCount> values_{};
};

}  // namespace joint::testing
