// Reset and vector table of both Cortex-M images (the firmware and the unit-test images): the
// smallest start-up a Cortex-M4F needs. The core fetches the initial stack pointer and the reset
// address from the table at the start of flash (sections.ld); Reset_Handler turns the FPU on,
// copies .data from flash, zeroes .bss, runs the static constructors, then main().
#include <cstddef>
#include <cstdint>
#include <cstdlib>

extern "C" {
// From sections.ld.
extern std::uint32_t __data_load[];
extern std::uint32_t __data_start[];
extern std::uint32_t __data_end[];
extern std::uint32_t __bss_start__[];
extern std::uint32_t __bss_end__[];
extern std::uint32_t __stack_top[];
using InitFunction = void (*)();
extern InitFunction __preinit_array_start[];
extern InitFunction __preinit_array_end[];
extern InitFunction __init_array_start[];
extern InitFunction __init_array_end[];

// main() itself, under a name C++ lets code call.
int hil_main(int argc, char** argv) __asm__("main");
void hil_platform_init();  // the image's own early set-up (semihosting, clocks)
[[noreturn]] void hil_fault(const char* what);

[[noreturn]] void Reset_Handler();
[[noreturn]] void HardFault_Handler() { hil_fault("hard fault"); }
[[noreturn]] void Unhandled_Handler() { hil_fault("unhandled exception"); }
// The firmware image defines its own; in an image that does not, the timer never ticks.
__attribute__((weak)) void SysTick_Handler() { hil_fault("SysTick without a handler"); }
}

// What the toolchain's crtbegin/crti would define (both images link without them): the handle
// static destructors register under, and newlib's init/fini hooks (the arrays below do the work).
extern "C" {
void* __dso_handle = nullptr;
void _init() {}
void _fini() {}
}

namespace {

// System Control Block: the Coprocessor Access Control Register.
volatile std::uint32_t& cpacr() { return *reinterpret_cast<volatile std::uint32_t*>(0xE000'ED88u); }

using Vector = void (*)();
constexpr std::size_t kVectors = 16 + 32;  // system exceptions + the external interrupts used

}  // namespace

extern "C" [[noreturn]] void Reset_Handler() {
  // CP10 and CP11 (the FPU) fully accessible, before any code that may use a float register.
  cpacr() = cpacr() | (0xFu << 20);
  asm volatile("dsb\n\tisb" ::: "memory");
  for (std::uint32_t *src = __data_load, *dst = __data_start; dst < __data_end;) *dst++ = *src++;
  for (std::uint32_t* dst = __bss_start__; dst < __bss_end__;) *dst++ = 0;
  hil_platform_init();
  for (InitFunction* f = __preinit_array_start; f < __preinit_array_end; ++f) (*f)();
  for (InitFunction* f = __init_array_start; f < __init_array_end; ++f) (*f)();
  // No command line on a microcontroller: the program's name only.
  static char name[] = "firmware";
  static char* argv[] = {name, nullptr};
  std::exit(hil_main(1, argv));
}

// Index 0: the initial stack pointer; 1: reset; 2..15: the system exceptions (15: SysTick);
// 16 on: the external interrupts, none used here (a real board's CAN controller's go there:
// docs/microcontroller.md). A constant table placed by the linker: no code builds it.
#define HIL_UNHANDLED_8 Unhandled_Handler, Unhandled_Handler, Unhandled_Handler, Unhandled_Handler, \
                        Unhandled_Handler, Unhandled_Handler, Unhandled_Handler, Unhandled_Handler
extern const Vector g_vectors[kVectors];
__attribute__((section(".isr_vector"), used)) const Vector g_vectors[kVectors] = {
    reinterpret_cast<Vector>(__stack_top),
    Reset_Handler,
    Unhandled_Handler,  // NMI
    HardFault_Handler,
    Unhandled_Handler, Unhandled_Handler, Unhandled_Handler,  // MemManage, BusFault, UsageFault
    nullptr, nullptr, nullptr, nullptr,                       // reserved
    Unhandled_Handler,                                        // SVCall
    Unhandled_Handler,                                        // debug monitor
    nullptr,                                                  // reserved
    Unhandled_Handler,                                        // PendSV
    SysTick_Handler,
    HIL_UNHANDLED_8, HIL_UNHANDLED_8, HIL_UNHANDLED_8, HIL_UNHANDLED_8,
};
#undef HIL_UNHANDLED_8
