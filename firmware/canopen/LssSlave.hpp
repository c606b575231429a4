// The LSS slave (CiA 305, Layer Setting Services): how a master finds a node by its identity
// (0x1018: vendor id, product code, revision, serial number) and gives it a node id and a bit
// timing, before or instead of any other configuration.
//
// Served: switch state global and selective, configure node-id, configure and activate bit
// timing, store configuration, inquire identity and node-id, identify remote slave, identify
// non-configured remote slave, fastscan. The Node owns one and feeds it every frame on
// cia305::kMasterCobId; the slave answers on cia305::kSlaveCobId through the Node.
//
// Node ids. The *active* id is the one the node runs with; a configured id is *pending* until
// the node resets communication (CiA 305), except for a node that had none (active 0xFF): the
// switch back to the waiting state makes it take the pending id at once (it resets communication
// and sends its boot-up), as CANopenNode and Lely do. Store configuration keeps the pending id
// and bit timing in the slave's own storage (not 0x1010's image: 0x1011 "restore defaults" must
// not forget which node a board is); load() applies it at start-up.
//
// The chain enable input (set_enabled): a modular robot's modules are wired in a chain, each
// module's enable output driving its downstream neighbour's enable input; a module asserts its
// output once it has an active node id. While its input is low a slave takes part in no LSS at
// all. So only the first module without an id answers fastscan, and a master numbers the chain
// in order (see hilrig.session.lss). A board not in a chain leaves the input high (the default).
//
// Hardware-agnostic and single-threaded, no heap; every request is 8 bytes or dropped.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include "Interfaces.hpp"
#include "board/cia305.hpp"

namespace co {

using LssState = cia305::LssState;
using LssCommand = cia305::LssCommand;

// The LSS address: 0x1018 sub 1..4, in fastscan's part order.
struct LssIdentity {
  std::uint32_t vendor_id = 0;
  std::uint32_t product_code = 0;
  std::uint32_t revision = 0;
  std::uint32_t serial_number = 0;

  std::uint32_t part(std::size_t n) const {
    switch (n) {
      case 0: return vendor_id;
      case 1: return product_code;
      case 2: return revision;
      default: return serial_number;
    }
  }
};

// What the node must do after a request.
enum class LssAction : std::uint8_t {
  None,
  ActivateNodeId,     // a node without an id got one: reset communication now (boot-up)
  ActivateBitTiming,  // the master switches the bus to the pending bit timing after the delay
};

struct LssOutcome {
  bool answer = false;  // send `answer_data` on cia305::kSlaveCobId
  std::array<std::uint8_t, cia305::kFrameBytes> answer_data{};
  LssAction action = LssAction::None;
  std::uint16_t switch_delay_ms = 0;  // ActivateBitTiming
};

struct LssCounters {
  std::uint32_t requests = 0;   // 8-byte frames given to process()
  std::uint32_t ignored = 0;    // not served in this state (or the chain input is low)
  std::uint32_t malformed = 0;  // not 8 bytes: dropped
  std::uint32_t answers = 0;
};

class LssSlave final {
 public:
  // `node_id`: the node's id before anything stored applies, 1..127 or 0xFF (none yet).
  LssSlave(const LssIdentity& identity, std::uint8_t node_id);
  LssSlave(const LssSlave&) = delete;
  LssSlave& operator=(const LssSlave&) = delete;

  // Where store configuration writes; nullptr (the default): storing is "not supported".
  void set_storage(ParameterStorage* storage) { storage_ = storage; }
  // A stored configuration, if any, replaces the pending and active node id and bit timing.
  // true: one was loaded.
  bool load();

  LssOutcome process(std::span<const std::uint8_t> data);

  // The node resets communication: the pending id becomes the active one, which it returns.
  std::uint8_t activate_pending_node_id();

  void set_enabled(bool enabled) { enabled_ = enabled; }
  bool enabled() const { return enabled_; }
  LssState state() const { return state_; }
  std::uint8_t active_node_id() const { return active_node_id_; }
  std::uint8_t pending_node_id() const { return pending_node_id_; }
  // CiA 301 table index of the bit timing configured (and stored); the port applies it.
  std::uint8_t pending_bit_timing() const { return pending_bit_timing_; }
  bool configured() const { return active_node_id_ != cia305::kNodeIdUnconfigured; }
  const LssIdentity& identity() const { return identity_; }
  const LssCounters& counters() const { return counters_; }

  // Stored configuration layout: u32 magic "LSS1", u8 node id, u8 bit timing index, u32 CRC-32
  // of the 6 bytes before it.
  static constexpr std::size_t kStoredBytes = 10;

 private:
  void switch_state_global(std::uint8_t mode, LssOutcome& outcome);
  void switch_state_selective(LssCommand command, std::uint32_t value, LssOutcome& outcome);
  void identify_remote(LssCommand command, std::uint32_t value, LssOutcome& outcome);
  void fastscan(std::span<const std::uint8_t> data, LssOutcome& outcome);
  void configure(std::span<const std::uint8_t> data, LssOutcome& outcome);
  bool store();
  bool non_configured() const {
    return active_node_id_ == cia305::kNodeIdUnconfigured && pending_node_id_ == cia305::kNodeIdUnconfigured;
  }

  LssIdentity identity_;
  ParameterStorage* storage_ = nullptr;
  LssState state_ = LssState::Waiting;
  std::uint8_t active_node_id_;
  std::uint8_t pending_node_id_;
  std::uint8_t pending_bit_timing_ = 0;
  bool enabled_ = true;
  // Switch state selective / identify remote slave: the parts received so far, in order.
  std::uint8_t selective_step_ = 0;
  std::uint8_t identify_step_ = 0;
  std::uint32_t identify_low_ = 0;
  // Fastscan: the identity part this slave compares next (its LSS sub).
  std::uint8_t fastscan_part_ = 0;
  LssCounters counters_;
};

}  // namespace co
