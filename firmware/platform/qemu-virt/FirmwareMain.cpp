// joint-firmware-virt.elf: the demo joint's firmware as a bare-metal image for qemu's 32-bit Arm
// `virt` machine, on a CTU CAN FD controller (qemu's ctucan_pci, joined to the rig's vcan by
// can-host-socketcan). The same pieces as the Linux and Cortex-M mains: the message board, the
// scheduler with the demo joint's components, the CANopen node and its views of them
// (platform/common), the hardware-in-the-loop registers; here on the controller's driver
// (CtuCanFd.hpp) through the interrupt-safe rings (InterruptCanPort.hpp), the generic timer, the
// GIC, and the pflash for the stored parameters and the LSS id (FlashStorage.hpp).
//
// Boot parameters (what the Linux firmware's command line says) come from qemu's fw_cfg file
// opt/hil/boot, one line of key=value words: node-id=N mode=lockstep|free period-us=N
// serial=N flash=0|1 (a drive behind pflash 1); the rig writes them (hilrig.session.baremetal). Lockstep: one control cycle per
// SYNC, the synchronous TPDOs right after it; free-running: one per timer deadline, absolute.
// The log goes to the UART; a fault prints its reason and stops qemu with status 1.
// count-cycles=N (`make bench`, free-running, under qemu -icount): after N control cycles the
// image prints what they cost in generic-timer ticks (mean, worst) and ends qemu with status 0.
#include <array>
#include <charconv>
#include <cstddef>
#include <cstdint>
#include <new>
#include <optional>
#include <span>
#include <string_view>

#include "CtuCanFd.hpp"
#include "FlashStorage.hpp"
#include "Machine.hpp"
#include "NodeOnRegisters.hpp"
#include "StartupArena.hpp"
#include "board/fields.hpp"
#include "canopen/Emcy.hpp"
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

// qemu's ctucan_pci (a Tedia PCIe card's ids): BAR 1 holds the cores, 0x4000 bytes each.
constexpr std::uint16_t kCtuCanVendor = 0x1760;
constexpr std::uint16_t kCtuCanDevice = 0xFF00;
constexpr std::uint32_t kCoresBar = 1;
constexpr std::uint32_t kSerialDefault = 0x5649'0001u;  // "VI": 0x1018:4 when the rig names none

struct BootParameters {
  std::uint8_t node_id = board::kNode.default_node_id;
  bool lockstep = true;
  std::uint32_t period_us = board::kNode.period_us;
  std::uint32_t serial = kSerialDefault;
  bool flash = false;  // qemu has a drive behind pflash 1
  std::uint32_t count_cycles = 0;  // >0: measure that many cycles, print their cost, end qemu
};

// "node-id=16 mode=lockstep period-us=1000 serial=0x12345678": unknown words are a fault (the
// rig and this image disagree), missing ones keep their defaults.
BootParameters parse_boot_parameters(std::string_view text) {
  BootParameters parameters;
  while (!text.empty()) {
    const std::size_t end = text.find_first_of(" \n");
    const std::string_view word = text.substr(0, end);
    text = end == std::string_view::npos ? std::string_view{} : text.substr(end + 1);
    if (word.empty()) continue;
    const std::size_t equals = word.find('=');
    const std::string_view key = word.substr(0, equals);
    std::string_view value = equals == std::string_view::npos ? std::string_view{} : word.substr(equals + 1);
    int base = 10;
    if (value.starts_with("0x")) {
      value.remove_prefix(2);
      base = 16;
    }
    std::uint32_t number = 0;
    const bool numeric = std::from_chars(value.data(), value.data() + value.size(), number, base).ec == std::errc{};
    if (key == "mode" && (word.ends_with("=lockstep") || word.ends_with("=free"))) {
      parameters.lockstep = word.ends_with("=lockstep");
    } else if (key == "node-id" && numeric && number <= 0xFF) {
      parameters.node_id = static_cast<std::uint8_t>(number);
    } else if (key == "period-us" && numeric && number >= board::kNode.period_us_min &&
               number <= board::kNode.period_us_max) {
      parameters.period_us = number;
    } else if (key == "count-cycles" && numeric) {
      parameters.count_cycles = number;
    } else if (key == "flash" && numeric && number <= 1) {
      parameters.flash = number == 1;
    } else if (key == "serial" && numeric) {
      parameters.serial = number;
    } else {
      virt::log("hilfw: bad boot parameter: ");
      virt::log(word);
      virt::log("\n");
      hil_fault("boot parameters");
    }
  }
  return parameters;
}

// The controller's registers, at the core's MMIO window.
class MmioRegisters {
 public:
  explicit MmioRegisters(std::uintptr_t base) : base_{base} {}
  std::uint32_t read(std::uint32_t offset) const { return virt::mmio32(base_ + offset); }
  void write(std::uint32_t offset, std::uint32_t value) { virt::mmio32(base_ + offset) = value; }

 private:
  std::uintptr_t base_;
};

using CanDriver = virt::ctucan::Driver<MmioRegisters>;

BootParameters g_boot;
std::optional<MmioRegisters> g_can_registers;
std::optional<CanDriver> g_can;
std::uint32_t g_can_interrupt = 0;
std::uint64_t g_ticks_per_period = 0;
std::uint64_t g_next_deadline = 0;
std::uint32_t g_timer_periods = 0;  // free-running: deadlines passed (hil_irq counts them)
bool g_free_running_timer = false;

std::uint32_t now_us() {
  static const std::uint64_t frequency = virt::counter_frequency_hz();
  return static_cast<std::uint32_t>(virt::counter_ticks() * 1'000'000u / frequency);
}

struct Application {
  Application() : demo_joint{board, registers.drivers(), static_cast<float>(g_boot.period_us) * 1e-6f} {}
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

alignas(co::Recorder) std::byte g_recorder_storage[sizeof(co::Recorder)];
platform::BoardFieldAccess<Application> g_field_access{g_app};
platform::HilIoOnRegisters<Application> g_hil_io{g_app};
platform::HeartbeatOnRegisters<Application> g_heartbeat_on_registers{g_app};
virt::FlashStorage g_parameter_flash{virt::kFlash1Base, virt::kFlashBlockBytes, 0};
virt::FlashStorage g_lss_flash{virt::kFlash1Base, virt::kFlashBlockBytes, 1};

class NoParameterStorage final : public co::ParameterStorage {
 public:
  bool save(std::span<const std::byte>) override { return false; }
  std::size_t load(std::span<std::byte>) override { return 0; }
};
NoParameterStorage g_no_storage;

void mask_interrupts() { asm volatile("cpsid i" ::: "memory"); }
void unmask_interrupts() { asm volatile("cpsie i" ::: "memory"); }

// The controller's frames the node queued, handed to it with the interrupt masked (the
// interrupt hands them over too).
void flush_transmit() {
  mask_interrupts();
  g_can->service_transmit();
  unmask_interrupts();
}

void arm_timer_for(const co::Node& node) {
  if (g_free_running_timer) return;  // the period's deadlines wake the loop already
  constexpr std::uint32_t kMaxIdleUs = 1'000'000;
  const std::uint32_t wait_us = node.us_until_next_timer(now_us(), kMaxIdleUs);
  virt::timer_set_deadline(virt::counter_ticks() + wait_us * static_cast<std::uint64_t>(virt::counter_frequency_hz()) / 1'000'000u);
}

}  // namespace

extern "C" void hil_irq() {
  const std::uint32_t interrupt = virt::gic_acknowledge();
  if (interrupt == g_can_interrupt && g_can) {
    g_can->on_interrupt();
  } else if (interrupt == virt::kVirtualTimerPpi) {
    if (g_free_running_timer) {
      // Absolute deadlines: a late cycle does not shift the ones after it.
      const std::uint64_t now = virt::counter_ticks();
      while (g_next_deadline <= now) {
        g_next_deadline += g_ticks_per_period;
        ++g_timer_periods;
      }
      virt::timer_set_deadline(g_next_deadline);
    } else {
      virt::timer_stop();  // the main loop sets the next one
    }
  }
  if (interrupt < 1020) virt::gic_end(interrupt);
}

extern "C" [[noreturn]] void hil_fault(const char* what) {
  asm volatile("cpsid i" ::: "memory");
  virt::log("hilfw: fault: ");
  virt::log(what);
  virt::log("\n");
  virt::exit_emulation(false);
}

int main() {
  std::array<char, 256> boot_text{};
  const std::size_t boot_length = virt::fw_cfg_read_file("opt/hil/boot", boot_text);
  g_boot = parse_boot_parameters(std::string_view{boot_text.data(), boot_length});

  const virt::PciFunction pci = virt::pci_find_and_enable(kCtuCanVendor, kCtuCanDevice);
  if (!pci.found || pci.bar[kCoresBar] == 0) hil_fault("no CTU CAN FD controller on the PCI bus (qemu -device ctucan_pci)");
  g_can_registers.emplace(pci.bar[kCoresBar]);
  g_can.emplace(*g_can_registers);
  if (!g_can->start()) hil_fault("the CTU CAN FD core does not answer (device id)");
  g_can_interrupt = pci.interrupt;

  virt::gic_init();
  virt::gic_enable(g_can_interrupt);
  virt::gic_enable(virt::kVirtualTimerPpi);

  const bool flash = g_boot.flash;
  co::ParameterStorage& storage = flash ? static_cast<co::ParameterStorage&>(g_parameter_flash) : g_no_storage;

  co::Recorder& recorder = *new (g_recorder_storage) co::Recorder;
  start_application();
  co::Node node{g_boot.node_id, g_can->port(), g_field_access, g_hil_io, storage, g_boot.serial};
  g_app->board.set_fault_hook({platform::report_ownership_violation, &node});
  co::FlagEmcyReporter fault_emcy{node, board::kFaultFlagsEmcy};
  ApplicationRebuild application_rebuild{node, fault_emcy};
  node.set_application_reset(&application_rebuild);
  node.set_recorder(&recorder);
  node.set_heartbeat_listener(&g_heartbeat_on_registers);
  node.set_acceptance_listener(&*g_can);
  if (flash) node.set_lss_storage(&g_lss_flash);
  node.set_timeout_clock(g_boot.lockstep ? co::TimeoutClock::ControlCycles : co::TimeoutClock::WallTime);

  g_ticks_per_period = static_cast<std::uint64_t>(virt::counter_frequency_hz()) * g_boot.period_us / 1'000'000u;
  if (!g_boot.lockstep) {
    g_free_running_timer = true;
    g_next_deadline = virt::counter_ticks() + g_ticks_per_period;
    virt::timer_set_deadline(g_next_deadline);
  }

  node.start(now_us());
  virt::log_hex("hilfw: qemu-virt, CTU CAN FD at ", static_cast<std::uint32_t>(pci.bar[kCoresBar]));
  virt::log_decimal(" (PCI slot ", pci.slot);
  virt::log_decimal(", INTID ", g_can_interrupt);
  virt::log_decimal("), node ", node.node_id());
  virt::log_hex(", serial ", g_boot.serial);
  virt::log(g_boot.lockstep ? ", lockstep mode" : ", free-running mode");
  virt::log_decimal(", period ", g_boot.period_us);
  virt::log(" us");
  virt::log(flash ? ", parameters in pflash 1" : ", parameters not stored (no pflash drive)");
  virt::log(node.parameter_load() == co::ParameterLoad::Loaded     ? " (loaded)\n"
            : node.parameter_load() == co::ParameterLoad::Rejected ? " (REJECTED: corrupt, defaults used)\n"
                                                                   : " (defaults)\n");
  unmask_interrupts();
  flush_transmit();

  core::CycleCounter cycles;
  std::uint32_t periods_done = 0;
  virt::ctucan::FaultState reported_fault_state = virt::ctucan::FaultState::ErrorActive;
  std::uint32_t reported_overruns = 0;
  std::uint64_t measured_ticks = 0;
  std::uint64_t worst_ticks = 0;
  auto run_cycle = [&](std::uint64_t periods) {
    const std::uint32_t cycle = cycles.advance(periods);
    const std::uint64_t started = virt::counter_ticks();
    g_app->scheduler.run_cycle(cycle);
    const std::uint64_t took = virt::counter_ticks() - started;
    measured_ticks += took;
    if (took > worst_ticks) worst_ticks = took;
    if (g_boot.count_cycles != 0 && cycles.run() == g_boot.count_cycles) {
      virt::log_decimal("hilfw: cycle cost: cycles ", cycles.run());
      virt::log_decimal(", ticks ", measured_ticks);
      virt::log_decimal(", worst ", worst_ticks);
      virt::log_decimal(", counter Hz ", virt::counter_frequency_hz());
      virt::log("\n");
      virt::exit_emulation(true);
    }
    fault_emcy.update(static_cast<std::uint32_t>(g_app->board.get(board::FieldId::fault_flags)));
    recorder.sample(cycle, [](board::FieldId id) { return g_app->board.get(id); });
  };
  for (;;) {
    const std::uint32_t woke_at = now_us();
    co::CanFrame frame;
    while (g_can->port().receive(frame) == co::ReceiveResult::Received) {
      const co::ProcessResult result = node.process(frame, woke_at);
      if (result.boot_sync) node.advance_control_time(g_boot.period_us);  // booting: its clock only
      if (result.sync) {
        if (g_boot.lockstep) {
          node.advance_control_time(g_boot.period_us);
          run_cycle(1);
        }
        node.transmit_synchronous_pdos(woke_at);
      }
      flush_transmit();
    }
    if (!g_boot.lockstep) {
      const std::uint32_t periods = *static_cast<volatile std::uint32_t*>(&g_timer_periods);
      if (periods != periods_done) {
        run_cycle(periods - periods_done);  // deadlines missed while the last cycle ran still count
        periods_done = periods;
      }
    }
    // The controller's news: bus-off and receive overruns as EMCY (CiA 301's communication codes).
    const virt::ctucan::FaultState fault_state = g_can->fault_state();
    if (fault_state != reported_fault_state) {
      reported_fault_state = fault_state;
      if (fault_state == virt::ctucan::FaultState::BusOff) node.report_emcy(co::emcy::bus_off());
    }
    const std::uint32_t overruns = g_can->counters().data_overruns + g_can->port().receive_overruns();
    if (overruns != reported_overruns) {
      reported_overruns = overruns;
      node.report_emcy(co::emcy::receive_overrun(0));
    }
    node.poll(now_us());
    flush_transmit();
    mask_interrupts();
    if (!node.sdo_segments_due()) {
      arm_timer_for(node);
      if (!g_can->port().received_pending()) asm volatile("wfi");  // a frame or the timer wakes the core
    }
    unmask_interrupts();
  }
}
