// Message board benchmarks, each beside a naive baseline measured in the same
// run; main() prints the ratios, since absolute times on shared machines are
// noise. Run: build/bin/fw_board_bench   (goals: get within 2x of a raw array
// read, a full 17-component cycle under 2 microseconds)
#include <benchmark/benchmark.h>

#include <array>
#include <cstdint>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "JointLikeComponents.hpp"
#include "NaiveBoard.hpp"
#include "core/MessageBoard.hpp"
#include "core/MessageBoardUser.hpp"
#include "core/Scheduler.hpp"

namespace bench {
namespace {

// The CANopen node's part: owns the bus-writable fields, streams the setpoint.
class NodeStandIn final : public core::ExternalWriter {
 public:
  explicit NodeStandIn(core::MessageBoard& board)
      : ExternalWriter(board, "canopen_node", {.writes = core::kBusWritableFields}) {}
  void write(F id, float value) { boardSet(id, value); }
};

void write_bus_defaults(const auto& write) {
  core::kBusWritableFields.for_each([&](F id) { write(id, board::info(id).default_value); });
  write(F::control_mode, 1.0f);
}

// Fields the get/set benchmarks rotate through (a constant id would let the
// compiler fold the index).
constexpr std::array<F, 8> kRotation{F::motor_velocity,   F::joint_torque,       F::velocity_kp,
                                     F::motor_position,    F::thermal_derate,     F::safe_state,
                                     F::spring_deflection, F::velocity_setpoint};

class ManualWriter final : public core::VirtualSensor {
 public:
  explicit ManualWriter(core::MessageBoard& board)
      : VirtualSensor(board, "writer",
                      {.writes = {F::motor_velocity, F::output_velocity, F::spring_deflection, F::joint_torque,
                                  F::winding_temperature}}) {}
  void update() override {}
  void write(F id, float value) { boardSet(id, value); }
};

constexpr std::array<F, 4> kWriteRotation{F::motor_velocity, F::output_velocity, F::spring_deflection, F::joint_torque};

void BM_Get_MessageBoard(benchmark::State& state) {
  core::MessageBoard board;
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(board.get(kRotation[i++ & 7U]));
  }
}

void BM_Get_RawArray(benchmark::State& state) {
  std::array<float, board::kFieldCount> raw{};
  benchmark::DoNotOptimize(raw.data());
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(raw[static_cast<std::size_t>(kRotation[i++ & 7U])]);
  }
}

void BM_Get_StringMap(benchmark::State& state) {
  NaiveBoard naive;
  for (const F id : kRotation) {
    naive.set(&naive, std::string(board::info(id).name), 1.0f);
  }
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(naive.get(std::string(board::info(kRotation[i++ & 7U]).name)));
  }
}

void BM_Set_MessageBoard(benchmark::State& state) {
  core::MessageBoard board;
  ManualWriter writer{board};
  if (!board.claim_writes(writer)) {
    state.SkipWithError("claim failed");
    return;
  }
  std::size_t i = 0;
  float value = 0.0f;
  for (auto _ : state) {
    writer.write(kWriteRotation[i++ & 3U], value);
    value += 1.0f;
  }
  benchmark::DoNotOptimize(board.get(F::motor_velocity));
}

void BM_Set_RawArray(benchmark::State& state) {
  std::array<float, board::kFieldCount> raw{};
  std::size_t i = 0;
  float value = 0.0f;
  for (auto _ : state) {
    raw[static_cast<std::size_t>(kWriteRotation[i++ & 3U])] = value;
    benchmark::ClobberMemory();
    value += 1.0f;
  }
  benchmark::DoNotOptimize(raw.data());
}

void BM_Set_StringMap(benchmark::State& state) {
  NaiveBoard naive;
  std::size_t i = 0;
  float value = 0.0f;
  for (auto _ : state) {
    naive.set(&naive, std::string(board::info(kWriteRotation[i++ & 3U]).name), value);
    value += 1.0f;
  }
  benchmark::DoNotOptimize(naive.get("motor_velocity"));
}

void BM_Cycle_MessageBoard(benchmark::State& state) {
  Hardware hardware;
  core::MessageBoard board;
  core::Scheduler scheduler{board};
  std::vector<std::unique_ptr<core::MessageBoardUser>> components;
  build_joint(hardware, [&](ComponentKind kind, std::string_view name, const Declarations& declarations, auto math) {
    components.push_back(std::make_unique<CoreAdapter<decltype(math)>>(board, kind, name, declarations, math));
    scheduler.add(*components.back());
  });
  NodeStandIn node{board};
  scheduler.add(node);
  if (const core::StartupStatus status = scheduler.start(); !status) {
    state.SkipWithError(status.message().c_str());
    return;
  }
  write_bus_defaults([&](F id, float value) { node.write(id, value); });
  std::uint32_t cycle = 0;
  for (auto _ : state) {
    ++cycle;
    feed_hardware(hardware, cycle);
    node.write(F::velocity_setpoint, 5.0f);
    scheduler.run_cycle(cycle);
  }
  benchmark::DoNotOptimize(hardware.motor_duty);
  if (board.total_refused_writes() != 0) {
    state.SkipWithError("a component's write was refused");
  }
  state.counters["components"] = static_cast<double>(scheduler.order().size());
}

void BM_Cycle_StringMap(benchmark::State& state) {
  Hardware hardware;
  NaiveBoard naive;
  // The same components in the order the scheduler chose for the core board.
  core::MessageBoard order_board;
  core::Scheduler order_scheduler{order_board};
  std::vector<std::unique_ptr<core::MessageBoardUser>> order_components;
  std::map<std::string_view, std::unique_ptr<NaiveComponent>> by_name;
  build_joint(hardware, [&](ComponentKind kind, std::string_view name, const Declarations& declarations, auto math) {
    order_components.push_back(
        std::make_unique<CoreAdapter<decltype(math)>>(order_board, kind, name, declarations, math));
    order_scheduler.add(*order_components.back());
    by_name.emplace(name, std::make_unique<NaiveAdapter<decltype(math)>>(naive, name, math));
  });
  if (const core::StartupStatus status = order_scheduler.start(); !status) {
    state.SkipWithError(status.message().c_str());
    return;
  }
  std::vector<NaiveComponent*> order;
  for (const core::MessageBoardUser* component : order_scheduler.order()) {
    order.push_back(by_name.at(component->name()).get());
  }
  const int node_identity = 0;
  write_bus_defaults([&](F id, float value) { naive.set(&node_identity, std::string(board::info(id).name), value); });
  std::uint32_t cycle = 0;
  for (auto _ : state) {
    ++cycle;
    feed_hardware(hardware, cycle);
    naive.set(&node_identity, "velocity_setpoint", 5.0f);
    naive.begin_cycle(cycle);
    for (NaiveComponent* component : order) {
      component->update();
    }
  }
  benchmark::DoNotOptimize(hardware.motor_duty);
  if (naive.refused_writes() != 0) {
    state.SkipWithError("a component's write was refused");
  }
}

BENCHMARK(BM_Get_MessageBoard);
BENCHMARK(BM_Get_RawArray);
BENCHMARK(BM_Get_StringMap);
BENCHMARK(BM_Set_MessageBoard);
BENCHMARK(BM_Set_RawArray);
BENCHMARK(BM_Set_StringMap);
BENCHMARK(BM_Cycle_MessageBoard);
BENCHMARK(BM_Cycle_StringMap);

// Prints as usual and keeps each benchmark's time per iteration in ns.
class RatioReporter final : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override {
    for (const Run& run : runs) {
      if (run.run_type == Run::RT_Iteration && !run.error_occurred) {
        ns_[run.benchmark_name()] =
            run.GetAdjustedRealTime() * 1e9 / benchmark::GetTimeUnitMultiplier(run.time_unit);
      }
    }
    ConsoleReporter::ReportRuns(runs);
  }

  // "get: 0.9 ns vs raw array 0.9 ns = 1.02x ..."; returns false if a goal is missed.
  bool print_ratios() const {
    const bool get_ok = ratio_line("get", "BM_Get_MessageBoard", "raw array", "BM_Get_RawArray", 2.0);
    ratio_line("get", "BM_Get_MessageBoard", "unordered_map<string>", "BM_Get_StringMap", 0.0);
    ratio_line("set", "BM_Set_MessageBoard", "raw array", "BM_Set_RawArray", 0.0);
    ratio_line("set", "BM_Set_MessageBoard", "unordered_map<string>", "BM_Set_StringMap", 0.0);
    ratio_line("cycle (17 components)", "BM_Cycle_MessageBoard", "unordered_map<string> board", "BM_Cycle_StringMap",
               0.0);
    const double cycle_ns = find("BM_Cycle_MessageBoard");
    const bool cycle_ok = cycle_ns > 0.0 && cycle_ns < 2000.0;
    std::printf("goal get <= 2x raw array: %s\n", get_ok ? "met" : "MISSED");
    std::printf("goal cycle < 2000 ns: %.0f ns, %s\n", cycle_ns, cycle_ok ? "met" : "MISSED");
    return get_ok && cycle_ok;
  }

 private:
  double find(const std::string& name) const {
    const auto it = ns_.find(name);
    return it == ns_.end() ? -1.0 : it->second;
  }

  bool ratio_line(const char* what, const std::string& ours, const char* baseline_name, const std::string& baseline,
                  double goal) const {
    const double ours_ns = find(ours);
    const double baseline_ns = find(baseline);
    if (ours_ns <= 0.0 || baseline_ns <= 0.0) {
      std::printf("%s: not measured\n", what);
      return false;
    }
    const double ratio = ours_ns / baseline_ns;
    std::printf("%s: %.2f ns vs %s %.2f ns = %.2fx\n", what, ours_ns, baseline_name, baseline_ns, ratio);
    return goal <= 0.0 || ratio <= goal;
  }

  std::map<std::string, double> ns_;
};

}  // namespace
}  // namespace bench

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) {
    return 1;
  }
  bench::RatioReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  benchmark::Shutdown();
  std::printf("\n");
  // Goals are reported, not enforced: timings on a shared machine are noise.
  reporter.print_ratios();
  return 0;
}
