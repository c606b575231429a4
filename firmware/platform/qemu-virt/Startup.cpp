// Reset and exception entry of the virt image (an Armv7-A core, Cortex-A15): the vector table
// (taken in Arm state, at VBAR), a stack for each mode an exception enters, the VFP/NEON unit on
// and .bss zeroed before any compiled code runs (the compiler may use NEON registers anywhere),
// then hil_start(): the MMU (Machine.cpp), the static constructors, main(). An IRQ saves the
// registers the procedure call standard lets a C++ function clobber, the VFP ones included, and
// calls hil_irq(); an abort or undefined instruction ends in hil_exception(), which names it.
#include <cstdint>
#include <cstdlib>

#include "Machine.hpp"

extern "C" {
using InitFunction = void (*)();
extern InitFunction __preinit_array_start[];
extern InitFunction __preinit_array_end[];
extern InitFunction __init_array_start[];
extern InitFunction __init_array_end[];

int hil_main(int argc, char** argv) __asm__("main");
[[noreturn]] void hil_start();
[[noreturn]] void hil_exception(std::uint32_t kind, std::uint32_t address);
void hil_irq();

// What the toolchain's crtbegin/crti would define (the image links without them).
void* __dso_handle = nullptr;
void _init() {}
void _fini() {}
}

asm(R"(
  .section .vectors, "ax", %progbits
  .arm
  .balign 32
  .global hil_vectors
hil_vectors:
  ldr pc, 1f
  ldr pc, 2f
  ldr pc, 3f
  ldr pc, 4f
  ldr pc, 5f
  nop
  ldr pc, 6f
  ldr pc, 7f
1: .word hil_reset
2: .word hil_undefined_entry
3: .word hil_svc_entry
4: .word hil_prefetch_abort_entry
5: .word hil_data_abort_entry
6: .word hil_irq_entry
7: .word hil_fiq_entry

  .text
  .arm
  .global hil_reset
  .type hil_reset, %function
hil_reset:
  cpsid aif
  ldr r0, =hil_vectors
  mcr p15, 0, r0, c12, c0, 0
  cps #0x12
  ldr sp, =__irq_stack_top
  cps #0x17
  ldr sp, =__abort_stack_top
  cps #0x1B
  ldr sp, =__abort_stack_top
  cps #0x13
  ldr sp, =__stack_top
  mrc p15, 0, r0, c1, c0, 2
  orr r0, r0, #(0xF << 20)
  mcr p15, 0, r0, c1, c0, 2
  isb
  mov r0, #(1 << 30)
  vmsr fpexc, r0
  ldr r0, =__bss_start__
  ldr r1, =__bss_end__
  mov r2, #0
0:
  cmp r0, r1
  strlo r2, [r0], #4
  blo 0b
  blx hil_start

  .type hil_irq_entry, %function
hil_irq_entry:
  sub lr, lr, #4
  push {r0-r3, r12, lr}
  vmrs r0, fpscr
  push {r0, r1}
  vpush {d0-d7}
  vpush {d16-d31}
  blx hil_irq
  vpop {d16-d31}
  vpop {d0-d7}
  pop {r0, r1}
  vmsr fpscr, r0
  ldm sp!, {r0-r3, r12, pc}^

hil_undefined_entry:
  mov r0, #0
  sub r1, lr, #4
  blx hil_exception
hil_svc_entry:
  mov r0, #1
  sub r1, lr, #4
  blx hil_exception
hil_prefetch_abort_entry:
  mov r0, #2
  mrc p15, 0, r1, c6, c0, 2
  blx hil_exception
hil_data_abort_entry:
  mov r0, #3
  mrc p15, 0, r1, c6, c0, 0
  blx hil_exception
hil_fiq_entry:
  mov r0, #4
  sub r1, lr, #4
  blx hil_exception
)");

extern "C" [[noreturn]] void hil_start() {
  virt::enable_mmu_and_fpu();
  for (InitFunction* f = __preinit_array_start; f < __preinit_array_end; ++f) (*f)();
  for (InitFunction* f = __init_array_start; f < __init_array_end; ++f) (*f)();
  static char name[] = "firmware";
  static char* argv[] = {name, nullptr};
  std::exit(hil_main(1, argv));
}

extern "C" [[noreturn]] void hil_fault(const char* what);

extern "C" [[noreturn]] void hil_exception(std::uint32_t kind, std::uint32_t address) {
  static constexpr const char* kNames[] = {"undefined instruction", "supervisor call", "prefetch abort",
                                           "data abort", "FIQ"};
  virt::log("hilfw: guest fault: ");
  virt::log(kNames[kind < 5 ? kind : 0]);
  virt::log_hex(" at ", address);
  virt::log("\n");
  hil_fault("exception");
}
