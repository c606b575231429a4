// The hardware of qemu's `virt` machine (32-bit Arm, `-M virt,highmem=off -cpu cortex-a15`) that
// this platform uses, each behind a few functions: the addresses come from the machine's memory
// map (qemu's hw/arm/virt.c, which the device tree it generates describes as well):
//   0x04000000  pflash 1 (CFI 01, 64 MiB, 256 KiB blocks): the stored parameters and the LSS id
//   0x08000000  GICv2 distributor, 0x08010000 its CPU interface
//   0x09000000  PL011 UART: the firmware's log (the rig's firmware log)
//   0x09020000  fw_cfg: the boot parameters the rig passes (opt/hil/boot)
//   0x10000000  PCI memory window; 0x3F000000 PCIe ECAM (bus 0); legacy INTA..D on SPIs 3..6
//   0x40000000  RAM: the image (firmware.ld)
// and the Armv7-A generic timer's virtual counter and timer (PPI 27).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>

namespace virt {

inline constexpr std::uintptr_t kFlash1Base = 0x0400'0000u;
inline constexpr std::uint32_t kFlashBlockBytes = 256 * 1024;
inline constexpr std::uintptr_t kGicDistributor = 0x0800'0000u;  // protocol-literal: the GIC distributor of the virt machine
inline constexpr std::uintptr_t kGicCpuInterface = 0x0801'0000u;
inline constexpr std::uintptr_t kUart = 0x0900'0000u;
inline constexpr std::uintptr_t kFwCfg = 0x0902'0000u;
inline constexpr std::uintptr_t kPciMemoryWindow = 0x1000'0000u;
inline constexpr std::uintptr_t kPciEcam = 0x3F00'0000u;
inline constexpr std::uint32_t kPciFirstIntxSpi = 3;
inline constexpr std::uint32_t kVirtualTimerPpi = 27;

inline volatile std::uint32_t& mmio32(std::uintptr_t address) {
  return *reinterpret_cast<volatile std::uint32_t*>(address);
}

// The MMU on with a flat map (RAM normal and cached, everything else device memory, no
// execution outside RAM), then the VFP/NEON unit: before any other code runs.
void enable_mmu_and_fpu();

// PL011: text out, polled (a line at start-up and at a fault; nothing in the control cycle).
void log(std::string_view text);
void log_hex(std::string_view label, std::uint32_t value);
void log_decimal(std::string_view label, std::uint64_t value);

// GICv2: the distributor and CPU interface on, `interrupt` (an INTID) enabled to CPU 0.
void gic_init();
void gic_enable(std::uint32_t interrupt);
std::uint32_t gic_acknowledge();  // the INTID (1023: spurious)
void gic_end(std::uint32_t interrupt);

// The generic timer: the virtual count in microseconds, and a compare deadline that raises PPI 27.
std::uint64_t counter_ticks();
std::uint32_t counter_frequency_hz();
void timer_set_deadline(std::uint64_t ticks);
void timer_stop();

// fw_cfg: the named file's bytes into `out`; its size (0: no such file).
std::size_t fw_cfg_read_file(std::string_view name, std::span<char> out);

// PCI on the ECAM: the first function with this vendor and device id on bus 0, its memory BARs
// given addresses in the PCI window and memory decoding and bus mastering switched on.
struct PciFunction {
  bool found = false;
  std::uint32_t slot = 0;
  std::array<std::uintptr_t, 6> bar{};
  std::uint32_t interrupt = 0;  // the GIC INTID of its INTA
};
PciFunction pci_find_and_enable(std::uint16_t vendor, std::uint16_t device);

// Stops the emulation with a status (semihosting SYS_EXIT; qemu runs with semihosting on):
// `success` false makes qemu exit with status 1, which the rig reports as a crash.
[[noreturn]] void exit_emulation(bool success);

}  // namespace virt
