// co::ParameterStorage in one 256 KiB block of the virt machine's second pflash (a CFI 01
// parallel NOR flash, Intel command set): the stored parameters in one block, the LSS
// configuration in the next. A record is a header word (kMagic), the length, the image's CRC-32
// and the image, programmed word by word after the block's erase; load() takes it only when
// all three agree, so a save cut short by a power loss reads as "nothing stored" (the node
// then answers with its defaults), never as a half-written image. The rig backs the flash with
// a file per board (hilrig.session.baremetal), so the parameters outlive a restart of qemu;
// without one (boot parameter flash=0) the image stores nothing, as the Linux firmware without --params.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "canopen/Interfaces.hpp"

namespace virt {

class FlashStorage final : public co::ParameterStorage {
 public:
  static constexpr std::uint32_t kMagic = 0x4849'4C50u;  // "PLIH": a record starts here

  // `block`: the block's index in the flash at `base`.
  FlashStorage(std::uintptr_t base, std::uint32_t block_bytes, std::uint32_t block)
      : address_{base + static_cast<std::uintptr_t>(block) * block_bytes}, block_bytes_{block_bytes} {}

  bool save(std::span<const std::byte> image) override;
  std::size_t load(std::span<std::byte> buffer) override;

 private:
  bool erase();
  bool program(std::uint32_t offset, std::uint32_t word);
  bool wait_ready();

  std::uintptr_t address_;
  std::uint32_t block_bytes_;
};

}  // namespace virt
