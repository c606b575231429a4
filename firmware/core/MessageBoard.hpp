// The message board of the seed: one float per board field, one writer per
// field. A plain table in fixed arrays sized by the generated field count; it
// does no I/O, timing or logging. Ownership comes from the writers'
// declarations (claim_writes, called by the Scheduler at start-up); a write by
// anyone else is refused, counted and reported through the fault hook.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "board/fields.hpp"
#include "core/FieldSet.hpp"
#include "core/StartupStatus.hpp"

namespace core {

class MessageBoardUser;

enum class SetResult : std::uint8_t {
  Ok,            // value stored, cycle of last write updated
  NotOwner,      // the writer does not own the field: value kept, refusal counted and reported
  UnknownField,  // the id is outside the generated table: nothing stored, refusal reported
};

struct WriteViolation {
  SetResult reason;                 // NotOwner or UnknownField
  FieldId field;
  const MessageBoardUser* offender;  // the component that called set()
  const MessageBoardUser* owner;     // the field's owner; nullptr if it has none
  std::uint32_t cycle;               // the board's cycle when the write was refused
};

// Called on every refused write, from inside set(), on the writer's thread.
// A plain function pointer and a context (no std::function: no heap, no RTTI);
// the CANopen node turns it into an EMCY.
using FaultHookFunction = void (*)(void* context, const WriteViolation& violation);
struct FaultHook {
  FaultHookFunction function = nullptr;
  void* context = nullptr;
};

class MessageBoard {
 public:
  // Every field starts at its default_value from board.toml, with no owner
  // and not yet written (has() is false).
  MessageBoard();
  MessageBoard(const MessageBoard&) = delete;
  MessageBoard& operator=(const MessageBoard&) = delete;

  // --- start-up ---------------------------------------------------------

  // Registers `user` as the owner of every field it declares as written.
  // Fails with DuplicateWriter, naming the field and both components, if one
  // of those fields already has another owner; then nothing is registered.
  // Claiming again the fields one already owns succeeds.
  StartupStatus claim_writes(const MessageBoardUser& user);

  // nullptr if nobody owns the field (or the id is outside the table).
  const MessageBoardUser* owner(FieldId id) const;

  void set_fault_hook(FaultHook hook) { fault_hook_ = hook; }

  // --- the cycle ----------------------------------------------------------

  // Stores `value` if `writer` owns the field. Otherwise the value is kept,
  // the refusal is counted for that field, and the fault hook is called.
  SetResult set(const MessageBoardUser& writer, FieldId id, float value) {
    const std::size_t i = field_index(id);
    if (i >= board::kFieldCount || owners_[i] != &writer) [[unlikely]] {
      return refuse(writer, id);
    }
    values_[i] = value;
    last_write_cycle_[i] = cycle_;
    written_.insert(id);
    return SetResult::Ok;
  }

  // True once the field has been written at least once.
  bool has(FieldId id) const { return written_.contains(id); }

  // A plain array read: no checks (that is what has() is for), and the id
  // must be one of the generated FieldIds.
  float get(FieldId id) const { return values_[field_index(id)]; }

  // Sets the cycle that following writes are stamped with. The Scheduler
  // calls it at the start of every cycle.
  void begin_cycle(std::uint32_t cycle) { cycle_ = cycle; }
  std::uint32_t cycle() const { return cycle_; }

  // The cycle of the field's last write; 0 if it was never written (see has()).
  std::uint32_t last_write_cycle(FieldId id) const {
    return is_valid_field(id) ? last_write_cycle_[field_index(id)] : 0;
  }

  // True if the field was never written, or its last write is more than
  // max_age_cycles before the current cycle. Wrap-around of the 32-bit cycle
  // counter is handled by unsigned subtraction.
  bool is_stale(FieldId id, std::uint32_t max_age_cycles) const {
    return !has(id) || cycle_ - last_write_cycle_[field_index(id)] > max_age_cycles;
  }

  // Writes to this field refused since start-up (by non-owners).
  std::uint32_t refused_writes(FieldId id) const {
    return is_valid_field(id) ? refused_writes_[field_index(id)] : 0;
  }
  // All refused writes, including those with an id outside the table.
  std::uint32_t total_refused_writes() const { return total_refused_writes_; }

  // The fields that hold a value: the seed's "generic module feedback".
  const FieldSet& written_fields() const { return written_; }

  // Calls visit(FieldId, float value) for every written field, in FieldId order.
  template <typename Visitor>
  void for_each_written(Visitor&& visit) const {
    written_.for_each([&](FieldId id) { visit(id, values_[field_index(id)]); });
  }

 private:
  SetResult refuse(const MessageBoardUser& writer, FieldId id);

  std::array<float, board::kFieldCount> values_{};
  std::array<const MessageBoardUser*, board::kFieldCount> owners_{};
  std::array<std::uint32_t, board::kFieldCount> last_write_cycle_{};
  std::array<std::uint32_t, board::kFieldCount> refused_writes_{};
  FieldSet written_;
  std::uint32_t cycle_ = 0;
  std::uint32_t total_refused_writes_ = 0;
  FaultHook fault_hook_;
};

}  // namespace core
