// Heartbeat consumer (CiA 301, 7.2.8.3.2.2; object 0x1016, 7.5.2.31): watches the heartbeats
// of up to board::kHeartbeatConsumers other nodes (on a joint: the bus master's).
//
// Entry n (0x1016 sub n): bits 16..23 the node id, bits 0..15 the consumer time in ms, bits
// 24..31 reserved (0). Node id 0 or time 0: the entry is unused. A written entry is not
// monitored until its node's next heartbeat (any state byte, the boot-up 0x00 too), so a bus
// that never carries that heartbeat never sees an event. From then on every heartbeat restarts
// the timer; when the consumer time passes without one, that is a heartbeat event, reported
// once: the entry then waits for the node's next heartbeat to monitor again.
//
// Time is whatever microsecond clock the caller passes (the node picks wall or control time,
// see Node::set_timeout_clock); it may wrap. Fixed-size, no heap.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>

#include "SdoAbort.hpp"
#include "TimeLeft.hpp"
#include "board/cia301.hpp"
#include "board/fields.hpp"

namespace co {

// `Entries` sub-indices; the node has board::kHeartbeatConsumers (HeartbeatConsumer below).
template <std::size_t Entries>
class BasicHeartbeatConsumer {
 public:
  static constexpr std::uint16_t kIndex = cia301::kHeartbeatConsumerIndex;
  static constexpr std::size_t kEntries = Entries;
  static constexpr std::uint32_t kReservedBits = 0xFF00'0000u;
  static constexpr std::uint8_t kMaxNodeId = cia301::kMaxNodeId;

  static constexpr std::uint8_t node_id_of(std::uint32_t entry) {
    return static_cast<std::uint8_t>(entry >> 16);
  }
  static constexpr std::uint16_t time_ms_of(std::uint32_t entry) {
    return static_cast<std::uint16_t>(entry & 0xFFFFu);
  }
  static constexpr bool is_used(std::uint32_t entry) {
    return node_id_of(entry) != 0 && time_ms_of(entry) != 0;
  }

  // Every entry unused (reset communication, before stored values are applied).
  void reset() { entries_.fill({}); }

  // The value of sub-index `sub` (1..kEntries).
  std::uint32_t entry(std::uint8_t sub) const { return entries_[sub - 1u].value; }

  // An SDO write of sub-index `sub` (1..kEntries): checked as CiA 301 says, then the entry
  // waits for its node's next heartbeat. Returns SdoAbort::None or the abort code.
  SdoAbort configure(std::uint8_t sub, std::uint32_t value) {
    if (sub == 0 || sub > kEntries) return SdoAbort::SubIndexDoesNotExist;
    if ((value & kReservedBits) != 0 || node_id_of(value) > kMaxNodeId) {
      return SdoAbort::ValueRangeExceeded;
    }
    // CiA 301: two used entries for one node id are refused (an unused one may name it).
    if (is_used(value)) {
      for (std::size_t n = 0; n < kEntries; ++n) {
        const std::uint32_t other = entries_[n].value;
        if (n + 1u != sub && is_used(other) && node_id_of(other) == node_id_of(value)) {
          return SdoAbort::ParameterIncompatible;
        }
      }
    }
    entries_[sub - 1u] = {value, Monitoring::Idle, 0};
    return SdoAbort::None;
  }

  // True when some used entry watches `node_id`.
  bool watches(std::uint8_t node_id) const {
    for (const Entry& e : entries_) {
      if (is_used(e.value) && node_id_of(e.value) == node_id) return true;
    }
    return false;
  }

  // A heartbeat (or boot-up) frame of `node_id`: its entry monitors (again) from `now_us`.
  void heartbeat(std::uint8_t node_id, std::uint32_t now_us) {
    for (Entry& e : entries_) {
      if (!is_used(e.value) || node_id_of(e.value) != node_id) continue;
      e.monitoring = Monitoring::Active;
      e.last_heartbeat_us = now_us;
    }
  }

  // Entries whose consumer time ran out by `now_us`: each becomes a heartbeat event, and
  // `event(node_id)` is called once for it.
  template <typename OnEvent>
  void check_timeouts(std::uint32_t now_us, OnEvent&& event) {
    for (Entry& e : entries_) {
      if (e.monitoring != Monitoring::Active) continue;
      if (now_us - e.last_heartbeat_us < std::uint32_t{time_ms_of(e.value)} * 1000u) continue;
      e.monitoring = Monitoring::Lost;
      event(node_id_of(e.value));
    }
  }

  // Microseconds from `now_us` until the first active entry's consumer time runs out (0 if one
  // already has); kNoTimerUs when none is timing. What an idle loop may sleep.
  std::uint32_t us_until_timeout(std::uint32_t now_us) const {
    std::uint32_t soonest = kNoTimerUs;
    for (const Entry& e : entries_) {
      if (e.monitoring != Monitoring::Active) continue;
      const std::uint32_t consumer_time_us = std::uint32_t{time_ms_of(e.value)} * 1000u;
      soonest = std::min(soonest, time_left_us(now_us, e.last_heartbeat_us, consumer_time_us));
    }
    return soonest;
  }

  // Entries whose heartbeat timed out and has not come back.
  std::uint8_t lost_entries() const {
    std::uint8_t lost = 0;
    for (const Entry& e : entries_) {
      if (e.monitoring == Monitoring::Lost) ++lost;
    }
    return lost;
  }

  // True while the entry of `sub` times heartbeats (it saw one since it was written).
  bool monitoring(std::uint8_t sub) const { return entries_[sub - 1u].monitoring == Monitoring::Active; }

 private:
  enum class Monitoring : std::uint8_t {
    Idle,    // unused, or written and waiting for the node's first heartbeat
    Active,  // heartbeats arrive; the timer runs
    Lost,    // the consumer time passed (the event was reported); waits for a heartbeat
  };
  struct Entry {
    std::uint32_t value = 0;
    Monitoring monitoring = Monitoring::Idle;
    std::uint32_t last_heartbeat_us = 0;
  };
  std::array<Entry, kEntries> entries_{};
};

using HeartbeatConsumer = BasicHeartbeatConsumer<board::kHeartbeatConsumers>;

}  // namespace co
