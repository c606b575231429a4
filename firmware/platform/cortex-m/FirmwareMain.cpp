// joint-firmware.elf: the demo joint's firmware for a Cortex-M4F. The same pieces as the Linux
// target's board application (platform/linux/hilfw/BoardRuntime.cpp): the message board, the
// scheduler with the demo joint's components, the CANopen node and its views of them
// (platform/common/NodeOnBoard.hpp, NodeOnRegisters.hpp), the
// hardware-in-the-loop registers; here on an interrupt-fed CAN port (InterruptCanPort.hpp) and
// the SysTick timer, free-running: one control cycle per tick. No heap (StartupArena.hpp), no
// exceptions, no RTTI, no operating system.
//
// Not yet on a real board: the CAN controller's registers and interrupts, and a flash sector
// for the stored parameters (docs/microcontroller.md).
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <new>
#include <optional>
#include <span>

#include "CycleBudget.hpp"
#include "InterruptCanPort.hpp"
#include "NodeOnRegisters.hpp"
#include "StartupArena.hpp"
#include "board/fields.hpp"
#include "canopen/FlagEmcy.hpp"
#include "canopen/Node.hpp"
#include "canopen/Recorder.hpp"
#include "core/CycleCounter.hpp"
#include "core/MessageBoard.hpp"
#include "core/Scheduler.hpp"
#include "joint/DemoJoint.hpp"
#include "joint/drivers/HilRegisters.hpp"

extern "C" [[noreturn]] void hil_fault(const char* what);

namespace {

// The mps2-an386's core clock (qemu's as well); an STM32G474 would say 170 MHz here.
constexpr std::uint32_t kCoreClockHz = 25'000'000;
constexpr std::uint32_t kPeriodUs = board::kNode.period_us;  // one control cycle per SysTick
// 0x1018:4. A real board derives it from the chip's unique id (an STM32G4's 96-bit UID).
constexpr std::uint32_t kSerialNumber = 0x4D34'0001u;

// SysTick (Armv7-M System Control Space).
volatile std::uint32_t& syst_csr() { return *reinterpret_cast<volatile std::uint32_t*>(0xE000'E010u); }
volatile std::uint32_t& syst_rvr() { return *reinterpret_cast<volatile std::uint32_t*>(0xE000'E014u); }
volatile std::uint32_t& syst_cvr() { return *reinterpret_cast<volatile std::uint32_t*>(0xE000'E018u); }

std::atomic<std::uint32_t> g_ticks{0};  // periods since start; SysTick_Handler counts them

std::uint32_t now_us() { return g_ticks.load(std::memory_order_relaxed) * kPeriodUs; }

// Frames the controller's interrupts hand over; 32 each way: a block-upload sub-block's worth.
cortexm::InterruptCanPort<32, 32> g_port;

// No parameter memory yet: 0x1010 answers "cannot store" (a real board: a flash sector).
class NoParameterStorage final : public co::ParameterStorage {
 public:
  bool save(std::span<const std::byte>) override { return false; }
  std::size_t load(std::span<std::byte>) override { return 0; }
};

// Everything NMT reset node resets, built in place (as on Linux).
struct Application {
  Application() : demo_joint{board, registers.drivers(), static_cast<float>(kPeriodUs) * 1e-6f} {}
  Application(const Application&) = delete;
  Application& operator=(const Application&) = delete;

  bool start() {
    return scheduler.add(bus_writer) && demo_joint.add_to(scheduler) && scheduler.start().ok();
  }

  core::MessageBoard board;
  core::Scheduler scheduler{board};
  platform::BusWriter bus_writer{board};
  joint::HilRegisters registers;
  joint::DemoJoint demo_joint;
};

std::optional<Application> g_app;

// Builds the application from an empty start-up arena and seals it.
void start_application() {
  cortexm::arena::reopen_empty();
  g_app.emplace();
  if (!g_app->start()) hil_fault("the application did not start");
  cortexm::arena::seal();
}

class ApplicationRebuild final : public co::ApplicationReset {
 public:
  ApplicationRebuild(co::Node& node, co::FlagEmcyReporter& fault_emcy) : node_{node}, fault_emcy_{fault_emcy} {}
  void reset_application() override {
    g_app.reset();
    start_application();
    g_app->board.set_fault_hook({platform::report_ownership_violation, &node_});
    fault_emcy_.forget();
  }

 private:
  co::Node& node_;
  co::FlagEmcyReporter& fault_emcy_;
};

// The field recorder's sample memory is static, constructed in main(): as a constant-initialized
// global it would sit in .data, its 64 KiB of zeros copied from flash at every reset.
alignas(co::Recorder) std::byte g_recorder_storage[sizeof(co::Recorder)];
platform::BoardFieldAccess<Application> g_field_access{g_app};
platform::HilIoOnRegisters<Application> g_hil_io{g_app};
platform::HeartbeatOnRegisters<Application> g_heartbeat_on_registers{g_app};
NoParameterStorage g_storage;

#ifdef HIL_BOOT_CHECK_CYCLES
// The boot check (cm_firmware_boot_check, run in `make test`): this image with one addition,
// after HIL_BOOT_CHECK_CYCLES control cycles it ends qemu through semihosting (SYS_EXIT,
// application exit: status 0). A fault never gets there: hil_fault spins, the runner times out.
[[noreturn]] void end_boot_check() {
  register std::uint32_t operation asm("r0") = 0x18;  // SYS_EXIT
  register std::uint32_t reason asm("r1") = 0x20026;  // ADP_Stopped_ApplicationExit
  asm volatile("bkpt 0xab" : : "r"(operation), "r"(reason) : "memory");
  hil_fault("semihosting exit returned");
}
#endif

#ifdef HIL_CYCLE_BUDGET_SCALE_PERCENT
// SysTick ticks since start: whole periods and the down-counter's progress in this one.
std::uint64_t systick_now() {
  for (;;) {
    const std::uint32_t before = g_ticks.load(std::memory_order_relaxed);
    const std::uint32_t counter = syst_cvr();
    if (g_ticks.load(std::memory_order_relaxed) == before) {
      return static_cast<std::uint64_t>(before) * (syst_rvr() + 1) + (syst_rvr() - counter);
    }
  }
}

// The cycle budget check (CycleBudget.hpp): each cycle's frames from the budget's master, the
// main loop's pass timed, the node's frames handed back; then the worst cycle against the
// budget (scaled by HIL_CYCLE_BUDGET_SCALE_PERCENT: the check that must fail), and the exit:
// 0 within the budget with the fault's EMCY seen and the SDO upload's segments answered.
template <typename Serve>
[[noreturn]] void measure_cycle_budget(co::Node& node, const Serve& serve, const std::uint32_t& ticks_done) {
  namespace budget = cortexm::budget;
  budget::Master master{board::kNode.default_node_id};
  constexpr std::uint32_t kNsPerTick = 1'000'000'000u / kCoreClockHz;  // one instruction a ns
  std::uint64_t worst = 0;
  std::uint32_t worst_cycle = 0;
  for (std::uint32_t n = 0; n < budget::kCycles; ++n) {
    while (g_ticks.load(std::memory_order_relaxed) == ticks_done) asm volatile("wfi");
    master.frames_of_cycle(n, [](const co::CanFrame& frame) { g_port.push_received(frame); });
    const std::uint64_t start = systick_now();
    serve();
    while (node.sdo_segments_due()) serve();
    const std::uint64_t spent = (systick_now() - start) * kNsPerTick;
    co::CanFrame sent;
    while (g_port.pop_to_transmit(sent)) master.sent(sent);
    if (spent > worst) {
      worst = spent;
      worst_cycle = n;
    }
  }
  const std::uint32_t limit =
      static_cast<std::uint32_t>(std::uint64_t{budget::budget_cycles(kPeriodUs)} * HIL_CYCLE_BUDGET_SCALE_PERCENT / 100);
  char line[240] = "cycle_budget: ";
  char* end = line + 14;
  end = budget::append(end, "worst_instructions", static_cast<std::uint32_t>(worst));
  end = budget::append(end, "worst_cycle", worst_cycle);
  end = budget::append(end, "cycles", budget::kCycles);
  end = budget::append(end, "budget_cycles", limit);
  end = budget::append(end, "period_us", kPeriodUs);
  end = budget::append(end, "mcu_clock_hz", board::kMcuClockHz);
  end = budget::append(end, "budget_percent", board::kCycleBudgetPercent);
  end = budget::append(end, "budget_scale_percent", HIL_CYCLE_BUDGET_SCALE_PERCENT);
  end = budget::append(end, "emcy_frames", master.emcy_frames());
  end = budget::append(end, "sdo_segments", master.sdo_segments());
  end[0] = '\n';
  end[1] = '\0';
  budget::write_line(line);
  budget::exit_with(worst <= limit && master.emcy_frames() > 0 && master.sdo_segments() > 0);
}
#endif

}  // namespace

extern "C" void SysTick_Handler() { g_ticks.fetch_add(1, std::memory_order_relaxed); }

extern "C" void hil_platform_init() {}

extern "C" [[noreturn]] void hil_fault(const char*) {
  // A real board logs the reason to a no-init RAM word and lets its watchdog reset it.
  asm volatile("cpsid i" ::: "memory");
  for (;;) {
  }
}

int main() {
  co::Recorder& recorder = *new (g_recorder_storage) co::Recorder;
  start_application();
  co::Node node{board::kNode.default_node_id, g_port, g_field_access, g_hil_io, g_storage, kSerialNumber};
  g_app->board.set_fault_hook({platform::report_ownership_violation, &node});
  co::FlagEmcyReporter fault_emcy{node, board::kFaultFlagsInfo};
  ApplicationRebuild application_rebuild{node, fault_emcy};
  node.set_application_reset(&application_rebuild);
  node.set_recorder(&recorder);
  node.set_heartbeat_listener(&g_heartbeat_on_registers);
  node.set_timeout_clock(co::TimeoutClock::WallTime);

  syst_rvr() = kCoreClockHz / 1'000'000u * kPeriodUs - 1;
  syst_cvr() = 0;
  syst_csr() = 0b111;  // processor clock, interrupt on, counter on
  node.start(now_us());

  core::CycleCounter cycles;
  std::uint32_t ticks_done = g_ticks.load(std::memory_order_relaxed);
  // One pass of the main loop: the frames received, the control cycle when a tick came, the
  // node's timers and SDO segments.
  const auto serve = [&] {
    co::CanFrame frame;
    while (g_port.receive(frame) == co::ReceiveResult::Received) {
      if (node.process(frame, now_us()).sync) node.transmit_synchronous_pdos(now_us());
    }
    // Ticks missed while the last cycle ran still count as time (CycleCounter).
    const std::uint32_t ticks = g_ticks.load(std::memory_order_relaxed);
    if (ticks != ticks_done) {
      const std::uint32_t cycle = cycles.advance(ticks - ticks_done);
      ticks_done = ticks;
      g_app->scheduler.run_cycle(cycle);
      fault_emcy.update(static_cast<std::uint32_t>(g_app->board.get(board::FieldId::fault_flags)));
      recorder.sample(cycle, [](board::FieldId id) { return g_app->board.get(id); });
#ifdef HIL_BOOT_CHECK_CYCLES
      if (cycles.run() == HIL_BOOT_CHECK_CYCLES) end_boot_check();
#endif
    }
    node.poll(now_us());
  };
#ifdef HIL_CYCLE_BUDGET_SCALE_PERCENT
  measure_cycle_budget(node, serve, ticks_done);
#endif
  for (;;) {
    serve();
    if (!node.sdo_segments_due()) asm volatile("wfi");  // the next tick or frame wakes the core
  }
}
