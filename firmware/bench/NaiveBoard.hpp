// The baseline the message board is measured against: the obvious board a
// first version would have, a std::unordered_map<std::string, float> with
// string keys, the seed's first-write-claims ownership and a last-write cycle
// per field, and components called through a virtual update().
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>

#include "board/fields.hpp"

namespace bench {

class NaiveBoard {
 public:
  void set(const void* writer, const std::string& key, float value) {
    Entry& entry = entries_[key];
    if (entry.owner == nullptr) {
      entry.owner = writer;
    } else if (entry.owner != writer) {
      ++refused_writes_;
      return;
    }
    entry.value = value;
    entry.last_write_cycle = cycle_;
    entry.written = true;
  }
  float get(const std::string& key) const {
    const auto it = entries_.find(key);
    return it == entries_.end() ? 0.0f : it->second.value;
  }
  bool is_stale(const std::string& key, std::uint32_t max_age_cycles) const {
    const auto it = entries_.find(key);
    return it == entries_.end() || !it->second.written || cycle_ - it->second.last_write_cycle > max_age_cycles;
  }
  void begin_cycle(std::uint32_t cycle) { cycle_ = cycle; }
  std::uint32_t refused_writes() const { return refused_writes_; }

 private:
  struct Entry {
    float value = 0.0f;
    const void* owner = nullptr;
    std::uint32_t last_write_cycle = 0;
    bool written = false;
  };
  std::unordered_map<std::string, Entry> entries_;
  std::uint32_t cycle_ = 0;
  std::uint32_t refused_writes_ = 0;
};

class NaiveComponent {
 public:
  explicit NaiveComponent(std::string_view name) : name_{name} {}
  NaiveComponent(const NaiveComponent&) = delete;
  NaiveComponent& operator=(const NaiveComponent&) = delete;
  virtual ~NaiveComponent() = default;
  virtual void update() = 0;
  std::string_view name() const { return name_; }

 private:
  std::string_view name_;
};

// Runs a component's math against the naive board: every access builds the
// string key from the field's name, as `board.get("motor_velocity")` would.
template <typename Math>
class NaiveAdapter final : public NaiveComponent {
 public:
  NaiveAdapter(NaiveBoard& board, std::string_view name, Math math)
      : NaiveComponent(name), board_{board}, math_{std::move(math)} {}
  void update() override { math_.step(*this); }

  float get(board::FieldId id) const { return board_.get(std::string(board::info(id).name)); }
  void set(board::FieldId id, float value) { board_.set(this, std::string(board::info(id).name), value); }
  bool is_stale(board::FieldId id, std::uint32_t max_age_cycles) const {
    return board_.is_stale(std::string(board::info(id).name), max_age_cycles);
  }

 private:
  NaiveBoard& board_;
  Math math_;
};

}  // namespace bench
