// Latched flag bits -> EMCY frames, as board.toml's [[bitset.bits]] say (generated FlagInfo
// tables such as board::kFaultFlagsInfo), so a CANopen master sees faults without polling the
// flags field:
//   - a bit with an EMCY and an `about` object: latching reports that EMCY naming the object
//     (its index in the manufacturer bytes); clearing clears it (an error reset frame);
//   - a bit whose EMCY names its object at run time: the raiser reported it already (e.g. the
//     board's refused write, naming the field), so latching sends nothing; clearing clears every
//     active error of that code;
//   - a bit without EMCY: nothing.
#pragma once

#include <cstdint>
#include <span>

#include "Node.hpp"
#include "board/fields.hpp"

namespace co {

class FlagEmcyReporter {
 public:
  // `node` must outlive the reporter; `bits` is a generated table with static storage.
  FlagEmcyReporter(Node& node, std::span<const board::FlagInfo> bits) : node_{node}, bits_{bits} {}
  FlagEmcyReporter(const FlagEmcyReporter&) = delete;
  FlagEmcyReporter& operator=(const FlagEmcyReporter&) = delete;

  // Reports the bits of `flags` that latched or cleared since the previous call.
  void update(std::uint32_t flags);
  // NMT reset node: the node cleared its errors, a fresh application has latched none.
  void forget() { reported_ = 0; }

 private:
  Node& node_;
  std::span<const board::FlagInfo> bits_;
  std::uint32_t reported_ = 0;
};

}  // namespace co
