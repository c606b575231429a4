// Instruction count of one control cycle, for `valgrind --tool=callgrind` (repeatable on a
// noisy machine, unlike a timing). Three loops of N cycles, one per run:
//
//   fw_cycle_count demo   N   the real joint::DemoJoint (20 components) on core::Scheduler,
//                             its HIL registers fed every cycle as the receive path would
//   fw_cycle_count core   N   the benchmark's 17 joint-like stand-ins on the core board
//   fw_cycle_count naive  N   the same stand-ins on the naive unordered_map<string> board
//   fw_cycle_count recorder_idle   N   the field recorder's end-of-cycle call, idle
//   fw_cycle_count recorder_armed  N   the same, armed with 8 channels (every cycle a sample
//                                      and a level trigger that never fires: its dearest state)
//
// Set-up is outside the counted region: run under
//   valgrind --tool=callgrind --collect-atstart=no --toggle-collect='hil_count_*' ...
// and divide the collected instructions by N (tools/bench.py does this).
#include <bit>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "JointLikeComponents.hpp"
#include "NaiveBoard.hpp"
#include "board/fields.hpp"
#include "canopen/Recorder.hpp"
#include "core/MessageBoard.hpp"
#include "core/MessageBoardUser.hpp"
#include "core/Scheduler.hpp"
#include "joint/DemoJoint.hpp"
#include "joint/drivers/HilRegisters.hpp"

namespace {

using bench::CoreAdapter;
using bench::F;

// The CANopen node's part: owns the bus-writable fields (as in main.cpp).
class BusWriter final : public core::ExternalWriter {
 public:
  explicit BusWriter(core::MessageBoard& board)
      : ExternalWriter(board, "canopen_node", {.writes = core::kBusWritableFields}) {}
  void write(F id, float value) { boardSet(id, value); }
};

void write_bus_defaults(const auto& write) {
  core::kBusWritableFields.for_each([&](F id) { write(id, board::info(id).default_value); });
  write(F::control_mode, 1.0f);  // velocity control: the controllers run
}

volatile std::int32_t g_sink = 0;

}  // namespace

// The counted regions: plain C names so that --toggle-collect finds them.
extern "C" __attribute__((noinline)) void hil_count_demo(core::Scheduler& scheduler, BusWriter& node,
                                                        joint::HilRegisters& registers, std::uint32_t cycles) {
  for (std::uint32_t cycle = 1; cycle <= cycles; ++cycle) {
    registers.write_motor_encoder(static_cast<std::uint16_t>(cycle * 7U));
    registers.write_output_encoder(static_cast<std::uint16_t>(cycle * 3U));
    registers.write_thermistor_adc(static_cast<std::uint16_t>(2000U + (cycle & 15U)));
    registers.write_motor_current(static_cast<std::int16_t>(500 + (cycle & 3U)));
    node.write(F::velocity_setpoint, 5.0f);  // the setpoint stream (RPDO) of every cycle
    scheduler.run_cycle(cycle);
    g_sink = registers.motor_duty_raw();
  }
}

extern "C" __attribute__((noinline)) void hil_count_core(core::Scheduler& scheduler, BusWriter& node,
                                                        bench::Hardware& hardware, std::uint32_t cycles) {
  for (std::uint32_t cycle = 1; cycle <= cycles; ++cycle) {
    bench::feed_hardware(hardware, cycle);
    node.write(F::velocity_setpoint, 5.0f);
    scheduler.run_cycle(cycle);
    g_sink = hardware.motor_duty;
  }
}

extern "C" __attribute__((noinline)) void hil_count_naive(bench::NaiveBoard& naive,
                                                         const std::vector<bench::NaiveComponent*>& order,
                                                         const void* node_identity, bench::Hardware& hardware,
                                                         std::uint32_t cycles) {
  for (std::uint32_t cycle = 1; cycle <= cycles; ++cycle) {
    bench::feed_hardware(hardware, cycle);
    naive.set(node_identity, "velocity_setpoint", 5.0f);
    naive.begin_cycle(cycle);
    for (bench::NaiveComponent* component : order) {
      component->update();
    }
    g_sink = hardware.motor_duty;
  }
}

// The recorder's two loops are the same code under two names, so callgrind counts each alone.
namespace {
__attribute__((always_inline)) inline void sample_cycles(co::Recorder& recorder, const core::MessageBoard& board,
                                                         std::uint32_t cycles) {
  for (std::uint32_t cycle = 1; cycle <= cycles; ++cycle) {
    // In the firmware a whole control cycle runs between two calls: the recorder's state is
    // loaded afresh each time. Without this the compiler tests an idle recorder once per loop.
    asm volatile("" ::: "memory");
    recorder.sample(cycle, [&](F id) { return board.get(id); });
  }
}
}  // namespace

extern "C" __attribute__((noinline)) void hil_count_recorder_idle(co::Recorder& recorder,
                                                                 const core::MessageBoard& board,
                                                                 std::uint32_t cycles) {
  sample_cycles(recorder, board, cycles);
}

extern "C" __attribute__((noinline)) void hil_count_recorder_armed(co::Recorder& recorder,
                                                                  const core::MessageBoard& board,
                                                                  std::uint32_t cycles) {
  sample_cycles(recorder, board, cycles);
}

namespace {

// Static, as in the firmware: 64 KiB of sample memory.
co::Recorder g_recorder;

int run_recorder(std::uint32_t cycles, bool armed) {
  namespace object = board::recorder;
  const core::MessageBoard board;  // every field at its default: the values do not change the cost
  g_recorder.reset();
  if (armed) {
    bool ok = g_recorder.write(object::kChannels, 0, 0) == co::SdoAbort::None;
    for (std::uint8_t channel = 1; channel <= 8; ++channel) {
      const board::FieldInfo& field = board::kFields[channel - 1u];
      ok = ok && g_recorder.write(object::kChannels, channel, field.index) == co::SdoAbort::None;
    }
    const auto level = static_cast<std::uint32_t>(board::RecorderTrigger::Level);
    const float never = board::info(F::motor_velocity).max;  // stays armed: the trigger is looked at every sample
    ok = ok && g_recorder.write(object::kChannels, 0, 8) == co::SdoAbort::None &&
         g_recorder.write(object::kSamples, 0, static_cast<std::uint32_t>(co::Recorder::kBufferValues / 8)) == co::SdoAbort::None &&
         g_recorder.write(object::kTrigger, object::trigger_sub::kSource, level) == co::SdoAbort::None &&
         g_recorder.write(object::kTrigger, object::trigger_sub::kField, board::info(F::motor_velocity).index) ==
             co::SdoAbort::None &&
         g_recorder.write(object::kTrigger, object::trigger_sub::kLevel, std::bit_cast<std::uint32_t>(never)) ==
             co::SdoAbort::None &&
         g_recorder.write(object::kTrigger, object::trigger_sub::kPreTriggerPercent, 10) == co::SdoAbort::None &&
         g_recorder.write(object::kState, 0, static_cast<std::uint32_t>(board::RecorderState::Armed)) ==
             co::SdoAbort::None;
    if (!ok) {
      std::fprintf(stderr, "fw_cycle_count: the recorder refused its settings\n");
      return 1;
    }
  }
  if (armed) {
    hil_count_recorder_armed(g_recorder, board, cycles);
  } else {
    hil_count_recorder_idle(g_recorder, board, cycles);
  }
  const bool expected = g_recorder.state() == (armed ? board::RecorderState::Armed : board::RecorderState::Idle);
  std::printf("recorder_%s: %u cycles, state %d\n", armed ? "armed" : "idle", cycles,
              static_cast<int>(g_recorder.state()));
  return expected ? 0 : 1;
}

int run_demo(std::uint32_t cycles) {
  core::MessageBoard board;
  core::Scheduler scheduler{board};
  BusWriter node{board};
  joint::HilRegisters registers;
  joint::DemoJoint demo{board, registers.drivers(), 0.001f};
  if (!scheduler.add(node) || !demo.add_to(scheduler)) return 1;
  if (const core::StartupStatus status = scheduler.start(); !status.ok()) {
    std::fprintf(stderr, "fw_cycle_count: %s\n", status.message().c_str());
    return 1;
  }
  write_bus_defaults([&](F id, float value) { node.write(id, value); });
  hil_count_demo(scheduler, node, registers, cycles);
  std::printf("demo: %u cycles, %zu components, refused writes %u\n", cycles, scheduler.order().size(),
              board.total_refused_writes());
  return board.total_refused_writes() == 0 ? 0 : 1;
}

// Builds the stand-ins on the core board; the naive run uses this only for the update order.
struct CoreJoint {
  bench::Hardware hardware;
  core::MessageBoard board;
  core::Scheduler scheduler{board};
  std::vector<std::unique_ptr<core::MessageBoardUser>> components;
  BusWriter node{board};
};

bool build_core(CoreJoint& joint, std::map<std::string_view, std::unique_ptr<bench::NaiveComponent>>* naive_by_name,
                bench::NaiveBoard* naive, bench::Hardware* naive_hardware) {
  bench::build_joint(joint.hardware, [&](core::ComponentKind kind, std::string_view name,
                                         const core::Declarations& declarations, auto math) {
    joint.components.push_back(
        std::make_unique<CoreAdapter<decltype(math)>>(joint.board, kind, name, declarations, math));
    joint.scheduler.add(*joint.components.back());
  });
  if (naive_by_name != nullptr) {
    bench::build_joint(*naive_hardware, [&](core::ComponentKind, std::string_view name, const core::Declarations&,
                                            auto math) {
      naive_by_name->emplace(name, std::make_unique<bench::NaiveAdapter<decltype(math)>>(*naive, name, math));
    });
  }
  joint.scheduler.add(joint.node);
  if (const core::StartupStatus status = joint.scheduler.start(); !status.ok()) {
    std::fprintf(stderr, "fw_cycle_count: %s\n", status.message().c_str());
    return false;
  }
  return true;
}

int run_core(std::uint32_t cycles) {
  CoreJoint joint;
  if (!build_core(joint, nullptr, nullptr, nullptr)) return 1;
  write_bus_defaults([&](F id, float value) { joint.node.write(id, value); });
  hil_count_core(joint.scheduler, joint.node, joint.hardware, cycles);
  std::printf("core: %u cycles, %zu components\n", cycles, joint.scheduler.order().size());
  return joint.board.total_refused_writes() == 0 ? 0 : 1;
}

int run_naive(std::uint32_t cycles) {
  CoreJoint order_joint;
  bench::NaiveBoard naive;
  bench::Hardware hardware;
  std::map<std::string_view, std::unique_ptr<bench::NaiveComponent>> by_name;
  if (!build_core(order_joint, &by_name, &naive, &hardware)) return 1;
  std::vector<bench::NaiveComponent*> order;
  for (const core::MessageBoardUser* component : order_joint.scheduler.order()) {
    const auto it = by_name.find(component->name());
    if (it != by_name.end()) order.push_back(it->second.get());
  }
  const int node_identity = 0;
  write_bus_defaults([&](F id, float value) { naive.set(&node_identity, std::string(board::info(id).name), value); });
  hil_count_naive(naive, order, &node_identity, hardware, cycles);
  std::printf("naive: %u cycles, %zu components\n", cycles, order.size());
  return naive.refused_writes() == 0 ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: fw_cycle_count demo|core|naive|recorder_idle|recorder_armed CYCLES\n");
    return 2;
  }
  const std::string_view what = argv[1];
  const auto cycles = static_cast<std::uint32_t>(std::strtoul(argv[2], nullptr, 10));
  if (what == "demo") return run_demo(cycles);
  if (what == "core") return run_core(cycles);
  if (what == "naive") return run_naive(cycles);
  if (what == "recorder_idle") return run_recorder(cycles, false);
  if (what == "recorder_armed") return run_recorder(cycles, true);
  std::fprintf(stderr, "fw_cycle_count: unknown loop '%s' (demo, core, naive, recorder_idle or recorder_armed)\n",
               argv[1]);
  return 2;
}
