#include "core/MessageBoard.hpp"

#include <string>

#include "core/MessageBoardUser.hpp"

namespace core {

MessageBoard::MessageBoard() {
  for (std::size_t i = 0; i < board::kFieldCount; ++i) {
    values_[i] = board::kFields[i].default_value;
  }
}

StartupStatus MessageBoard::claim_writes(const MessageBoardUser& user) {
  const FieldSet& writes = user.declarations().writes;
  bool conflict = false;
  FieldId conflicting_field{};
  writes.for_each([&](FieldId id) {
    const MessageBoardUser* current = owners_[field_index(id)];
    if (!conflict && current != nullptr && current != &user) {
      conflict = true;
      conflicting_field = id;
    }
  });
  if (conflict) {
    const MessageBoardUser& current = *owners_[field_index(conflicting_field)];
    return StartupStatus::failure(
        StartupError::DuplicateWriter,
        "field '" + std::string(board::info(conflicting_field).name) + "' is declared as written by both " +
            describe(current) + " and " + describe(user) + "; every field has exactly one writer");
  }
  writes.for_each([&](FieldId id) { owners_[field_index(id)] = &user; });
  return StartupStatus::success();
}

const MessageBoardUser* MessageBoard::owner(FieldId id) const {
  return is_valid_field(id) ? owners_[field_index(id)] : nullptr;
}

SetResult MessageBoard::refuse(const MessageBoardUser& writer, FieldId id) {
  const bool known = is_valid_field(id);
  const SetResult reason = known ? SetResult::NotOwner : SetResult::UnknownField;
  if (known) {
    ++refused_writes_[field_index(id)];
  }
  ++total_refused_writes_;
  if (fault_hook_.function != nullptr) {
    const WriteViolation violation{reason, id, &writer, owner(id), cycle_};
    fault_hook_.function(fault_hook_.context, violation);
  }
  return reason;
}

}  // namespace core
