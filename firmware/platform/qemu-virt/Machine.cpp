// The virt machine's devices (Machine.hpp): register layouts as the Arm architecture (VMSAv7
// short descriptors, the generic timer), the GICv2 and PL011 manuals, the PCI Local Bus and
// PCIe ECAM specifications and qemu's fw_cfg interface document them.
#include "Machine.hpp"

#include <algorithm>
#include <array>
#include <cstring>

namespace virt {
namespace {

// VMSAv7 short-descriptor translation table: 4096 1 MiB sections.
alignas(16 * 1024) std::array<std::uint32_t, 4096> g_translation_table;

constexpr std::uint32_t kSection = 0b10;
constexpr std::uint32_t kAccessFull = 0b11u << 10;
constexpr std::uint32_t kNormalWriteBack = (0b001u << 12) | (1u << 3) | (1u << 2);  // TEX 001, C, B
constexpr std::uint32_t kDevice = 1u << 2;                                           // TEX 000, B: shareable device
constexpr std::uint32_t kExecuteNever = 1u << 4;
constexpr std::uint32_t kRamFirstSection = 0x400;  // protocol-literal: the section index of 0x40000000

volatile std::uint8_t& mmio8(std::uintptr_t address) { return *reinterpret_cast<volatile std::uint8_t*>(address); }
volatile std::uint16_t& mmio16(std::uintptr_t address) { return *reinterpret_cast<volatile std::uint16_t*>(address); }

std::uint32_t ecam_address(std::uint32_t slot, std::uint32_t offset) {
  return static_cast<std::uint32_t>(kPciEcam) | (slot << 15) | offset;  // bus 0, function 0
}

}  // namespace

void enable_mmu_and_fpu() {
  for (std::uint32_t i = 0; i < g_translation_table.size(); ++i) {
    const std::uint32_t attributes = i >= kRamFirstSection ? kNormalWriteBack : kDevice | kExecuteNever;
    g_translation_table[i] = (i << 20) | kAccessFull | attributes | kSection;
  }
  const auto table = reinterpret_cast<std::uintptr_t>(g_translation_table.data());
  asm volatile(
      "mcr p15, 0, %0, c2, c0, 2\n\t"  // TTBCR: TTBR0 only, short descriptors
      "mcr p15, 0, %1, c2, c0, 0\n\t"  // TTBR0
      "mcr p15, 0, %2, c3, c0, 0\n\t"  // DACR: every domain manager
      "mcr p15, 0, %0, c8, c7, 0\n\t"  // TLBIALL
      "mcr p15, 0, %0, c7, c5, 0\n\t"  // ICIALLU
      "dsb\n\tisb" ::"r"(0u),
      "r"(static_cast<std::uint32_t>(table)), "r"(0xFFFF'FFFFu)
      : "memory");
  std::uint32_t sctlr = 0;
  asm volatile("mrc p15, 0, %0, c1, c0, 0" : "=r"(sctlr));
  sctlr &= ~((1u << 1) | (1u << 28) | (1u << 29));          // no alignment check, no TEX remap, no AF
  sctlr |= (1u << 0) | (1u << 2) | (1u << 11) | (1u << 12);  // MMU, data cache, branch prediction, instruction cache
  asm volatile("mcr p15, 0, %0, c1, c0, 0\n\tisb" ::"r"(sctlr) : "memory");

  std::uint32_t cpacr = 0;
  asm volatile("mrc p15, 0, %0, c1, c0, 2" : "=r"(cpacr));
  cpacr |= 0xFu << 20;  // CP10, CP11: full access
  asm volatile("mcr p15, 0, %0, c1, c0, 2\n\tisb" ::"r"(cpacr) : "memory");
  asm volatile("vmsr fpexc, %0" ::"r"(1u << 30) : "memory");  // FPEXC.EN
}

void log(std::string_view text) {
  for (const char c : text) {
    while ((mmio32(kUart + 0x18) & (1u << 5)) != 0) {  // FR.TXFF
    }
    mmio32(kUart) = static_cast<std::uint8_t>(c);
  }
}

void log_hex(std::string_view label, std::uint32_t value) {
  std::array<char, 11> text{'0', 'x'};
  for (int i = 0; i < 8; ++i) {
    const std::uint32_t nibble = (value >> (28 - 4 * i)) & 0xFu;
    text[2 + i] = static_cast<char>(nibble < 10 ? '0' + nibble : 'A' + nibble - 10);
  }
  log(label);
  log(std::string_view{text.data(), 10});
}

void log_decimal(std::string_view label, std::uint64_t value) {
  std::array<char, 20> text{};
  std::size_t start = text.size();
  do {
    text[--start] = static_cast<char>('0' + value % 10);
    value /= 10;
  } while (value != 0);
  log(label);
  log(std::string_view{text.data() + start, text.size() - start});
}

void gic_init() {
  mmio32(kGicDistributor + 0x000) = 1;      // GICD_CTLR: forward interrupts
  mmio32(kGicCpuInterface + 0x004) = 0xFF;  // GICC_PMR: every priority passes
  mmio32(kGicCpuInterface + 0x000) = 1;     // GICC_CTLR: signal them to the core
}

void gic_enable(std::uint32_t interrupt) {
  mmio8(kGicDistributor + 0x400 + interrupt) = 0xA0;                 // protocol-literal: a GIC register offset (GICD_IPRIORITYR)
  if (interrupt >= 32) mmio8(kGicDistributor + 0x800 + interrupt) = 1;  // GICD_ITARGETSR: CPU 0
  mmio32(kGicDistributor + 0x100 + 4 * (interrupt / 32)) = 1u << (interrupt % 32);  // protocol-literal: a GIC register offset (GICD_ISENABLER)
}

std::uint32_t gic_acknowledge() { return mmio32(kGicCpuInterface + 0x00C) & 0x3FFu; }  // protocol-literal: the INTID field of GICC_IAR
void gic_end(std::uint32_t interrupt) { mmio32(kGicCpuInterface + 0x010) = interrupt; }

std::uint64_t counter_ticks() {
  std::uint32_t low = 0;
  std::uint32_t high = 0;
  asm volatile("isb\n\tmrrc p15, 1, %0, %1, c14" : "=r"(low), "=r"(high));  // CNTVCT
  return (static_cast<std::uint64_t>(high) << 32) | low;
}

std::uint32_t counter_frequency_hz() {
  std::uint32_t frequency = 0;
  asm volatile("mrc p15, 0, %0, c14, c0, 0" : "=r"(frequency));  // CNTFRQ
  return frequency;
}

void timer_set_deadline(std::uint64_t ticks) {
  asm volatile("mcrr p15, 3, %0, %1, c14" ::"r"(static_cast<std::uint32_t>(ticks)),
               "r"(static_cast<std::uint32_t>(ticks >> 32)));  // CNTV_CVAL
  asm volatile("mcr p15, 0, %0, c14, c3, 1\n\tisb" ::"r"(1u));   // CNTV_CTL: enabled, not masked
}

void timer_stop() { asm volatile("mcr p15, 0, %0, c14, c3, 1\n\tisb" ::"r"(0u)); }

std::size_t fw_cfg_read_file(std::string_view name, std::span<char> out) {
  auto select = [](std::uint16_t key) { mmio16(kFwCfg + 8) = static_cast<std::uint16_t>((key >> 8) | (key << 8)); };
  auto read_be = [](unsigned bytes) {
    std::uint32_t value = 0;
    for (unsigned i = 0; i < bytes; ++i) value = (value << 8) | mmio8(kFwCfg);
    return value;
  };
  select(0x19);  // FW_CFG_FILE_DIR
  const std::uint32_t files = read_be(4);
  for (std::uint32_t f = 0; f < files; ++f) {
    const std::uint32_t size = read_be(4);
    const auto key = static_cast<std::uint16_t>(read_be(2));
    (void)read_be(2);
    std::array<char, 56> file_name{};
    for (char& c : file_name) c = static_cast<char>(mmio8(kFwCfg));
    if (std::string_view{file_name.data()} != name) continue;
    select(key);
    const std::size_t length = std::min<std::size_t>(size, out.size());
    for (std::size_t i = 0; i < length; ++i) out[i] = static_cast<char>(mmio8(kFwCfg));
    return length;
  }
  return 0;
}

PciFunction pci_find_and_enable(std::uint16_t vendor, std::uint16_t device) {
  PciFunction function;
  for (std::uint32_t slot = 0; slot < 32; ++slot) {
    const std::uint32_t id = mmio32(ecam_address(slot, 0x00));
    if (id != (static_cast<std::uint32_t>(device) << 16 | vendor)) continue;
    function.found = true;
    function.slot = slot;
    std::uintptr_t next = kPciMemoryWindow;
    for (std::uint32_t bar = 0; bar < function.bar.size(); ++bar) {
      volatile std::uint32_t& reg = mmio32(ecam_address(slot, 0x10 + 4 * bar));
      reg = 0xFFFF'FFFFu;
      const std::uint32_t probe = reg;
      if (probe == 0 || (probe & 1u) != 0) continue;  // absent, or an I/O BAR
      const std::uint32_t size = ~(probe & ~0xFu) + 1;
      next = (next + size - 1) & ~static_cast<std::uintptr_t>(size - 1);
      reg = static_cast<std::uint32_t>(next);
      function.bar[bar] = next;
      next += size;
    }
    mmio32(ecam_address(slot, 0x04)) = 0b110;  // command: memory space, bus master
    // INTA of the slot, swizzled onto the host bridge's four lines (the device tree's interrupt-map).
    function.interrupt = 32 + kPciFirstIntxSpi + slot % 4;
    return function;
  }
  return function;
}

[[noreturn]] void exit_emulation(bool success) {
  const std::uint32_t reason = success ? 0x20026u : 0x20023u;  // ApplicationExit, RunTimeErrorUnknown
  std::array<std::uint32_t, 2> block{reason, 0};
  register std::uint32_t operation asm("r0") = 0x18;  // SYS_EXIT
  register std::uint32_t argument asm("r1") = reason;
  asm volatile("svc 0xab" : : "r"(operation), "r"(argument), "r"(block.data()) : "memory");
  for (;;) asm volatile("wfi");
}

}  // namespace virt
