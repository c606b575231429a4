// A fixed-size set of board fields: one bit per board::FieldId, no heap.
// Components declare their writes and reads with it, and the board lists
// the fields that hold a value with it.
#pragma once

#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <initializer_list>

#include "board/fields.hpp"

namespace core {

using board::FieldId;

constexpr std::size_t field_index(FieldId id) { return static_cast<std::size_t>(id); }

// True for the ids of the generated table; false for a value cast from an
// out-of-range integer (which every bounds-checked entry point refuses).
constexpr bool is_valid_field(FieldId id) { return field_index(id) < board::kFieldCount; }

class FieldSet {
 public:
  constexpr FieldSet() = default;
  constexpr FieldSet(std::initializer_list<FieldId> ids) {
    for (const FieldId id : ids) {
      insert(id);
    }
  }

  // Every field whose table entry satisfies the predicate,
  // e.g. `FieldSet::where([](const board::FieldInfo& f) { return f.stored; })`.
  template <typename Predicate>
  static constexpr FieldSet where(Predicate predicate) {
    FieldSet set;
    for (std::size_t i = 0; i < board::kFieldCount; ++i) {
      if (predicate(board::kFields[i])) {
        set.insert(static_cast<FieldId>(i));
      }
    }
    return set;
  }

  // Out-of-range ids are not stored: a set only ever holds real fields.
  constexpr void insert(FieldId id) {
    if (is_valid_field(id)) {
      words_[word_of(id)] |= bit_of(id);
    }
  }
  constexpr void erase(FieldId id) {
    if (is_valid_field(id)) {
      words_[word_of(id)] &= ~bit_of(id);
    }
  }
  constexpr bool contains(FieldId id) const {
    return is_valid_field(id) && (words_[word_of(id)] & bit_of(id)) != 0;
  }

  constexpr std::size_t size() const {
    std::size_t count = 0;
    for (const std::uint64_t word : words_) {
      count += static_cast<std::size_t>(std::popcount(word));
    }
    return count;
  }
  constexpr bool empty() const { return size() == 0; }

  // Calls visit(FieldId) for every member, in FieldId order.
  template <typename Visitor>
  constexpr void for_each(Visitor&& visit) const {
    for (std::size_t w = 0; w < kWords; ++w) {
      std::uint64_t word = words_[w];
      while (word != 0) {
        const auto bit = static_cast<std::size_t>(std::countr_zero(word));
        visit(static_cast<FieldId>(w * kBitsPerWord + bit));
        word &= word - 1;  // clear the lowest set bit
      }
    }
  }

  friend constexpr FieldSet operator|(FieldSet a, const FieldSet& b) {
    for (std::size_t w = 0; w < kWords; ++w) {
      a.words_[w] |= b.words_[w];
    }
    return a;
  }
  friend constexpr FieldSet operator&(FieldSet a, const FieldSet& b) {
    for (std::size_t w = 0; w < kWords; ++w) {
      a.words_[w] &= b.words_[w];
    }
    return a;
  }
  friend constexpr bool operator==(const FieldSet&, const FieldSet&) = default;

 private:
  static constexpr std::size_t kBitsPerWord = 64;
  static constexpr std::size_t kWords = (board::kFieldCount + kBitsPerWord - 1) / kBitsPerWord;

  static constexpr std::size_t word_of(FieldId id) { return field_index(id) / kBitsPerWord; }
  static constexpr std::uint64_t bit_of(FieldId id) {
    return std::uint64_t{1} << (field_index(id) % kBitsPerWord);
  }

  std::array<std::uint64_t, kWords> words_{};
};

// The fields a bus master may write (board.toml: access = "rw"): commands
// and parameters. The CANopen node declares these as its writes.
inline constexpr FieldSet kBusWritableFields =
    FieldSet::where([](const board::FieldInfo& field) { return field.access == board::Access::ReadWrite; });

}  // namespace core
