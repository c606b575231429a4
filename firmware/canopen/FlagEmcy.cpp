#include "FlagEmcy.hpp"

namespace co {

void FlagEmcyReporter::update(std::uint32_t flags) {
  for (const board::FlagInfo& bit : bits_) {
    if (!bit.emcy) continue;
    const std::uint32_t mask = bit.mask();
    const bool raised = (flags & mask) != 0 && (reported_ & mask) == 0;
    const bool cleared = (flags & mask) == 0 && (reported_ & mask) != 0;
    if (!bit.about_index) {
      if (cleared) node_.clear_emcy(board::info(*bit.emcy).code);
      continue;
    }
    const EmcyReport report = emcy::report(*bit.emcy, *bit.about_index);
    if (raised) node_.report_emcy(report);
    if (cleared) node_.clear_emcy(report);
  }
  reported_ = flags;
}

}  // namespace co
