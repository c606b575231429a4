// The board application of hilfw::run_board (hilfw/Board.hpp): a board's firmware for a Linux
// target on SocketCAN, the same for every board. Compiled once per board (it includes the board's
// generated header); the board's side reaches it through detail::BoardSlot.
//
// Wires the pieces together (the board itself stays a plain table): the message board, the
// scheduler with the board's components, the CANopen node (owner of the bus-writable
// fields), the hardware-in-the-loop registers, and one event-loop thread that feeds CAN frames
// to the node and runs control cycles, either one per received SYNC (lockstep) or on its own
// absolute-deadline timer (free-running).
#include "hilfw/Board.hpp"

#include <poll.h>
#include <signal.h>
#include <sys/signalfd.h>
#include <sys/timerfd.h>
#include <time.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "CommandLine.hpp"
#include "FileParameterStorage.hpp"
#include "FileProgramStore.hpp"
#include "SocketCanPort.hpp"
#include "SoftwareVersion.hpp"
#include "board/cia305.hpp"
#include "board/fields.hpp"
#include "canopen/FlagEmcy.hpp"
#include "canopen/Node.hpp"
#include "canopen/ParameterImage.hpp"
#include "canopen/Recorder.hpp"
#include "core/CycleCounter.hpp"
#include "core/MessageBoard.hpp"
#include "core/MessageBoardUser.hpp"
#include "core/Scheduler.hpp"

namespace hilfw::detail {
namespace {

using linuxhw::Mode;
using linuxhw::Options;

// 0x1018:4 when --serial is not given: stable for one board (the same machine and the same
// non-volatile files give the same serial after a restart), different for boards whose files
// differ. CRC-32 of /etc/machine-id and the absolute path of the LSS store (or the parameter
// file, or the interface and node id when nothing is stored).
std::uint32_t serial_number_default(const Options& options) {
  std::string seed;
  if (std::ifstream machine_id{"/etc/machine-id"}; machine_id) std::getline(machine_id, seed);
  std::error_code error;
  const std::string& file = !options.lss_store.empty() ? options.lss_store : options.params_file;
  // Appended piece by piece: `":" + std::string` trips a false -Wrestrict of GCC 12 at -O2.
  seed += ':';
  if (!file.empty()) {
    seed += std::filesystem::absolute(file, error).string();
  } else {
    seed += options.can_interface;
    seed += ':';
    seed += std::to_string(options.node_id);
  }
  std::vector<std::byte> bytes(seed.size());
  std::memcpy(bytes.data(), seed.data(), seed.size());
  return co::parameter_image::crc32(bytes);
}

// The emulated chain enable line (LssSlave's doc): a file per wire, which exists while the wire
// is high. The upstream module's output file is this module's input file.
bool chain_input_high(const std::string& path) { return path.empty() || ::access(path.c_str(), F_OK) == 0; }

void set_chain_output(const std::string& path, bool high) {
  if (path.empty()) return;
  if (high) {
    const std::string temporary = path + ".tmp";
    if (std::FILE* file = std::fopen(temporary.c_str(), "w")) {
      std::fputs("1\n", file);
      std::fclose(file);
      std::rename(temporary.c_str(), path.c_str());
    }
  } else {
    std::remove(path.c_str());
  }
}

// Exit codes: 0 clean stop, 1 start-up failure (bus, schedule), 2 bad command line (linuxhw::kExitUsage).
constexpr int kExitStartupFailure = 1;

// The executable's name in every message (BoardInfo::program, else argv[0]'s file name).
std::string g_program;

// --inject-rogue-write-at-cycle's help, with the EMCY code and fault bit the table gives.
std::string rogue_write_help(const BoardInfo& info) {
  if (!info.rogue_target) {
    return "FAULT INJECTION for hardware-in-the-loop tests: not offered by this board (its main names\n"
           "no BoardInfo::rogue_target); any value but 0 is refused";
  }
  const board::FieldInfo& target = board::info(*info.rogue_target);
  std::array<char, 160> fault_bit{};
  if (board::kOwnershipViolationBit) {
    std::snprintf(fault_bit.data(), fault_bit.size(), ",\nfault_flags bit %u (ownership violation) latched, safe state",
                  static_cast<unsigned>(*board::kOwnershipViolationBit));
  }
  std::array<char, 512> text{};
  std::snprintf(text.data(), text.size(),
                "FAULT INJECTION for hardware-in-the-loop tests, never for a real board: at control\n"
                "cycle N (1 = the first) an extra module that owns no field writes %.*s.\n"
                "The board must refuse it: value kept, refusal counted, EMCY 0x%04X naming 0x%04X%s. 0 = off",
                static_cast<int>(target.name.size()), target.name.data(),
                static_cast<unsigned>(board::emcy_code::kOwnershipViolation), static_cast<unsigned>(target.index),
                fault_bit.data());
  return text.data();
}

std::uint32_t now_us() {
  timespec now{};
  clock_gettime(CLOCK_MONOTONIC, &now);
  return static_cast<std::uint32_t>(static_cast<std::uint64_t>(now.tv_sec) * 1'000'000u +
                                    static_cast<std::uint64_t>(now.tv_nsec) / 1000u);
}

// poll()'s timeout while idle: until the node's next timer, rounded up to whole milliseconds
// (never early), and at most a second, so a timer this loop does not know of is late by no more.
int idle_wait_ms(const co::Node& node, std::uint32_t now) {
  constexpr std::uint32_t kMaxIdleUs = 1'000'000;
  const std::uint32_t wait_us = node.us_until_next_timer(now, kMaxIdleUs);
  return static_cast<int>((wait_us + 999u) / 1000u);
}

// Without --params nothing is stored; 0x1010 answers "cannot store" through the node.
class NoParameterStorage final : public co::ParameterStorage {
 public:
  bool save(std::span<const std::byte>) override { return false; }
  std::size_t load(std::span<std::byte>) override { return 0; }
};

// Fault injection for HIL tests (--inject-rogue-write-at-cycle): a module that declares no
// writes, so it owns nothing, and at one cycle writes a field another component owns. It exists
// so a scenario can watch the board's single-writer rule hold on the real bus.
class RogueWriter final : public core::Module {
 public:
  RogueWriter(core::MessageBoard& board, std::uint32_t at_cycle, board::FieldId target, float value)
      : Module(board, "rogue_writer", {}), at_cycle_{at_cycle}, target_{target}, value_{value} {}

  void update() override {
    if (board().cycle() == at_cycle_) boardSet(target_, value_);
  }

 private:
  std::uint32_t at_cycle_;
  board::FieldId target_;
  float value_;
};

// Everything NMT reset node resets: the board's application (the slot: board, scheduler,
// registers, components) and the rogue writer on its board. Rebuilt in place on reset node, so
// after it every object the firmware does not store is at its power-on value, as after a power
// cycle.
class Application {
 public:
  Application(BoardSlot& slot, const Options& options, const BoardInfo& info)
      : slot_{slot}, options_{options}, info_{info} {}
  Application(const Application&) = delete;
  Application& operator=(const Application&) = delete;

  // false: a component came too late or the ownership/schedule check failed (message printed).
  bool build_and_start() {
    rogue_writer_.reset();
    slot_.build(static_cast<float>(options_.period_us) * 1e-6f);
    if (options_.rogue_write_cycle != 0) {
      rogue_writer_.emplace(slot_.board(), options_.rogue_write_cycle, *info_.rogue_target, info_.rogue_value);
    }
    if (!slot_.add_components() || (rogue_writer_ && !slot_.scheduler().add(*rogue_writer_))) {
      std::fprintf(stderr, "%s: start-up error: components added after the scheduler started\n", g_program.c_str());
      return false;
    }
    if (const core::StartupStatus status = slot_.scheduler().start(); !status.ok()) {
      std::fprintf(stderr, "%s: start-up error: %s\n", g_program.c_str(), status.message().c_str());
      return false;
    }
    return true;
  }

  BoardSlot& slot() { return slot_; }
  core::MessageBoard& board() { return slot_.board(); }
  bool rogue() const { return rogue_writer_.has_value(); }

 private:
  BoardSlot& slot_;
  const Options& options_;
  const BoardInfo& info_;
  std::optional<RogueWriter> rogue_writer_;
};

// NMT reset node: a fresh application in place of the old one, wired to the node again.
class ApplicationRebuild final : public co::ApplicationReset {
 public:
  explicit ApplicationRebuild(Application& app) : app_{app} {}
  void attach(co::Node& node, co::FlagEmcyReporter& fault_emcy) {
    node_ = &node;
    fault_emcy_ = &fault_emcy;
  }
  void reset_application() override {
    // The same components started before; a failure here is a firmware bug, not a user error.
    if (!app_.build_and_start()) failed_ = true;
    app_.board().set_fault_hook({platform::report_ownership_violation, node_});
    fault_emcy_->forget();
  }
  bool failed() const { return failed_; }

 private:
  Application& app_;
  co::Node* node_ = nullptr;
  co::FlagEmcyReporter* fault_emcy_ = nullptr;
  bool failed_ = false;
};

// The field recorder's sample memory is static, as it would be on a microcontroller.
co::Recorder g_recorder;

void print_to_stdout(void*, std::string_view text) { std::fwrite(text.data(), 1, text.size(), stdout); }

// The table's fault flags as the FlagEmcyReporter reads them; 0 for a table without them.
std::uint32_t fault_flags(const core::MessageBoard& message_board) {
  return board::kFaultFlagsField ? static_cast<std::uint32_t>(message_board.get(*board::kFaultFlagsField)) : 0;
}

// `exec_path`: set when 0x1F51 started a downloaded image; run_board execv()s it once everything
// here is closed.
int run(const Options& options, const BoardInfo& info, BoardSlot& slot, std::string& exec_path) {
  Application app{slot, options, info};
  if (!app.build_and_start()) return kExitStartupFailure;
  if (options.print_schedule) {
    slot.scheduler().print_schedule(print_to_stdout, nullptr);
    return 0;
  }

  linuxhw::SocketCanPort port;
  if (std::string error; !port.open(options.can_interface, error)) {
    std::fprintf(stderr, "%s: %s\n", g_program.c_str(), error.c_str());
    return kExitStartupFailure;
  }
  std::unique_ptr<co::ParameterStorage> storage;
  if (options.params_file.empty()) {
    storage = std::make_unique<NoParameterStorage>();
  } else {
    storage = std::make_unique<linuxhw::FileParameterStorage>(options.params_file);
  }
  const std::uint32_t serial_number = options.serial_number.value_or(serial_number_default(options));
  co::Node node{static_cast<std::uint8_t>(options.node_id), port, slot.field_access(), slot.hil_io(), *storage,
                serial_number};
  node.set_software_version(linuxhw::software_version());
  std::unique_ptr<linuxhw::FileProgramStore> program_store;
  if (!options.image_dir.empty()) {
    program_store = std::make_unique<linuxhw::FileProgramStore>(options.image_dir);
    node.set_program_store(program_store.get());
  }
  std::unique_ptr<linuxhw::FileParameterStorage> lss_storage;
  if (!options.lss_store.empty()) {
    lss_storage = std::make_unique<linuxhw::FileParameterStorage>(options.lss_store);
    node.set_lss_storage(lss_storage.get());
  }
  app.board().set_fault_hook({platform::report_ownership_violation, &node});
  // Newly latched fault bits become EMCY frames and cleared ones error resets, as board.toml's
  // [[bitset]] fault_flags says (each bit's emcy and about); a table without it has none.
  co::FlagEmcyReporter fault_emcy{node, board::kFaultFlagsEmcy};
  ApplicationRebuild application_rebuild{app};
  application_rebuild.attach(node, fault_emcy);
  node.set_application_reset(&application_rebuild);
  node.set_recorder(&g_recorder);
  node.set_heartbeat_listener(&slot.heartbeat_listener());
  // The socket takes the node's accepted set at start() and whenever the bus changes it; the
  // node tells it before it answers, so a master never talks to a filter that lags.
  static_assert(co::Node::kMaxAcceptedIds <= linuxhw::SocketCanPort::kMaxAcceptedIds);
  if (options.acceptance_filter) node.set_acceptance_listener(&port);
  // The clock of the timeouts on peers (heartbeat consumer, SDO server): in lockstep, simulation
  // time (each SYNC's cycle advances it by the period, so a rig sending the master's heartbeat
  // every k cycles sees a trip at an exact cycle, and an SDO client slowed by a loaded host is
  // not cut off mid-transfer, whatever the host's speed); free-running, the wall clock.
  node.set_timeout_clock(options.mode == Mode::Lockstep ? co::TimeoutClock::ControlCycles
                                                         : co::TimeoutClock::WallTime);

  // SIGINT/SIGTERM arrive as readable data on a file descriptor: the loop finishes the frame
  // or cycle at hand and exits cleanly, with nothing half-written.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  sigprocmask(SIG_BLOCK, &stop_signals, nullptr);
  const int signal_fd = signalfd(-1, &stop_signals, SFD_NONBLOCK | SFD_CLOEXEC);

  int timer_fd = -1;
  if (options.mode == Mode::Free) {
    timer_fd = timerfd_create(CLOCK_MONOTONIC, TFD_NONBLOCK | TFD_CLOEXEC);
    itimerspec spec{};
    clock_gettime(CLOCK_MONOTONIC, &spec.it_value);
    spec.it_interval.tv_nsec = static_cast<long>(options.period_us) * 1000;
    if (options.period_us >= 1'000'000u) {
      spec.it_interval.tv_sec = options.period_us / 1'000'000u;
      spec.it_interval.tv_nsec = static_cast<long>(options.period_us % 1'000'000u) * 1000;
    }
    // Absolute deadlines: a late cycle does not shift the ones after it.
    timerfd_settime(timer_fd, TFD_TIMER_ABSTIME, &spec, nullptr);
  }

  node.set_lss_enabled(chain_input_high(options.chain_in));
  node.start(now_us());
  bool chain_output = node.has_node_id();
  set_chain_output(options.chain_out, chain_output);
  if (app.rogue()) {
    const std::string_view target = board::info(*info.rogue_target).name;
    std::fprintf(stderr, "%s: FAULT INJECTION: rogue write of %.*s at cycle %u\n", g_program.c_str(),
                 static_cast<int>(target.size()), target.data(), options.rogue_write_cycle);
  }
  const std::string_view version = linuxhw::software_version();
  std::fprintf(stderr, "%s: node %d%s, version %.*s, serial 0x%08X, on %s%s, %s mode, period %u us, parameters %s (%s)\n",
               g_program.c_str(), node.node_id(), node.has_node_id() ? "" : " (none yet: LSS only)",
               static_cast<int>(version.size()), version.data(), serial_number,
               options.can_interface.c_str(),
               options.acceptance_filter ? "" : " (no acceptance filter: every frame)",
               options.mode == Mode::Lockstep ? "lockstep" : "free-running", options.period_us,
               options.params_file.empty() ? "not stored" : options.params_file.c_str(),
               node.parameter_load() == co::ParameterLoad::Loaded        ? "loaded"
               : node.parameter_load() == co::ParameterLoad::Rejected    ? "REJECTED: corrupt, defaults used"
                                                                         : "defaults");

  core::CycleCounter cycles;
  auto run_cycle = [&](std::uint64_t periods) {
    const std::uint32_t cycle = cycles.advance(periods);
    slot.scheduler().run_cycle(cycle);
    const core::MessageBoard& message_board = slot.board();
    fault_emcy.update(fault_flags(message_board));
    // What the cycle left on the board; idle, this is one comparison.
    g_recorder.sample(cycle, [&](board::FieldId id) { return message_board.get(id); });
  };

  bool running = true;
  while (running) {
    std::array<pollfd, 3> fds{{{port.fd(), POLLIN, 0}, {signal_fd, POLLIN, 0}, {timer_fd, POLLIN, 0}}};
    const nfds_t count = timer_fd >= 0 ? 3 : 2;
    // Asleep until a frame, a signal, the cycle timer or the node's next timer (heartbeat,
    // event TPDO, a timeout): an idle node in lockstep wakes for its heartbeat only, not every
    // millisecond (sixteen idle modules in the emulated VM spent a vCPU on that). No wait while
    // a block upload has segments to send (each pass sends a bounded number, then serves frames).
    // No wait either while the port holds frames it has read but not handed out.
    const bool work_at_hand = node.sdo_segments_due() || port.has_buffered_frames();
    const int ready = ::poll(fds.data(), count, work_at_hand ? 0 : idle_wait_ms(node, now_us()));
    if (ready < 0 && errno != EINTR) {
      std::fprintf(stderr, "%s: poll failed: %s\n", g_program.c_str(), std::strerror(errno));
      return kExitStartupFailure;
    }
    if ((fds[1].revents & POLLIN) != 0) {
      running = false;
    }
    // The chain enable input, read before the frames that woke us: a module whose upstream
    // neighbour just got its id answers the master's next LSS request.
    if (!node.has_node_id()) node.set_lss_enabled(chain_input_high(options.chain_in));
    if (timer_fd >= 0 && (fds[2].revents & POLLIN) != 0) {
      std::uint64_t expirations = 0;
      if (::read(timer_fd, &expirations, sizeof(expirations)) == sizeof(expirations) && expirations > 0) {
        run_cycle(expirations);  // deadlines missed while the last cycle ran still count as time
      }
    }
    // One clock read for what this wake-up found, not one a frame: they all arrived before it.
    // Under user-mode Linux (the bus stage's VM) a clock read is a system call the host traps,
    // about 30 us; a module read it six times a cycle.
    const std::uint32_t woke_at = now_us();
    co::CanFrame frame;
    while (port.receive(frame) == co::ReceiveResult::Received) {
      const co::ProcessResult result = node.process(frame, woke_at);
      if (application_rebuild.failed()) {
        std::fprintf(stderr, "%s: reset node: the application did not start again\n", g_program.c_str());
        return kExitStartupFailure;
      }
      if (result.boot_sync) node.advance_control_time(options.period_us);  // booting: its clock only
      if (result.sync) {
        if (options.mode == Mode::Lockstep) {
          node.advance_control_time(options.period_us);  // a lost heartbeat reaches this cycle
          run_cycle(1);
        }
        node.transmit_synchronous_pdos(woke_at);
      }
      // 0x1F51 start with a checked image staged; its SDO answer is out.
      if (node.program_start_requested()) break;
    }
    if (node.program_start_requested()) {
      exec_path = program_store->promote_staged();
      if (exec_path.empty()) {
        std::fprintf(stderr, "%s: cannot start the downloaded image: %s\n", g_program.c_str(),
                     program_store->last_error().c_str());
        return kExitStartupFailure;
      }
      std::fprintf(stderr, "%s: starting the downloaded image %s\n", g_program.c_str(), exec_path.c_str());
      running = false;
      continue;
    }
    node.poll(woke_at);
    if (node.has_node_id() != chain_output) {
      chain_output = node.has_node_id();
      set_chain_output(options.chain_out, chain_output);
      std::fprintf(stderr, "%s: node id %d%s\n", g_program.c_str(), node.node_id(),
                   chain_output ? " configured over LSS" : " gone (LSS only)");
    }
  }

  const co::NodeCounters& counters = node.counters();
  std::fprintf(stderr,
               "%s: stopped after %llu cycles; overruns %llu; frames received %u, ignored %u, "
               "malformed %u, SDO aborts %u, RPDO length errors %u, TPDOs sent %u, EMCY %u, send failures %u, "
               "bus error frames %u, receive overruns %u, board refused writes %u, acceptance filter failures %u\n",
               g_program.c_str(), static_cast<unsigned long long>(cycles.run()), static_cast<unsigned long long>(cycles.skipped()),
               counters.frames_received,
               counters.frames_ignored, counters.frames_malformed, counters.sdo_aborts_sent,
               counters.rpdo_length_errors, counters.tpdos_sent, counters.emcy_sent, counters.send_failures,
               port.counters().error_frames, port.counters().receive_overruns, app.board().total_refused_writes(),
               port.counters().filter_failures);
  return 0;
}

}  // namespace

int run_board(int argc, char** argv, const BoardInfo& info, BoardSlot& slot) {
  g_program = !info.program.empty() ? std::string{info.program}
                                    : std::filesystem::path{argc > 0 ? argv[0] : "firmware"}.filename().string();
  Options options;
  options.node_id = board::kNode.default_node_id;
  options.period_us = board::kNode.period_us;
  const linuxhw::CommandLineText text{g_program,          info.description,         cia305::kNodeIdUnconfigured,
                                      rogue_write_help(info), board::kNode.period_us_min, board::kNode.period_us_max};
  if (const std::optional<int> exit_code = linuxhw::parse_command_line(argc, argv, text, options)) {
    return *exit_code;
  }
  if (options.rogue_write_cycle != 0 && !info.rogue_target) {
    std::fprintf(stderr,
                 "%s: --inject-rogue-write-at-cycle: this board offers no rogue write (name a field in "
                 "BoardInfo::rogue_target of its main), or leave the option out\n",
                 g_program.c_str());
    return linuxhw::kExitUsage;
  }
  std::string exec_path;
  const int exit_code = run(options, info, slot, exec_path);
  if (exec_path.empty()) return exit_code;
  // Same arguments, new image: it starts as after a power cycle and sends its boot-up.
  ::execv(exec_path.c_str(), argv);
  std::fprintf(stderr, "%s: cannot execute %s: %s\n", g_program.c_str(), exec_path.c_str(), std::strerror(errno));
  return kExitStartupFailure;
}

}  // namespace hilfw::detail
