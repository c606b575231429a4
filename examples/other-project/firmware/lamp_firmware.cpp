// lamp-firmware: the toy lamp's firmware (examples/other-project/board.toml) for a Linux target
// on SocketCAN, built from hilrig's firmware core and CANopen engine. The rig's command line:
//   lamp-firmware --can CHANNEL --node-id N --mode lockstep|free --period-us P [--image-dir DIR]
// (--image-dir: where the rig's session lets a firmware keep program downloads, CiA 302-3; the
// lamp takes none, so it has no use for it).
// In lockstep each SYNC runs one control cycle and its synchronous TPDOs follow; free-running,
// an absolute-deadline timer runs the cycles. SIGINT/SIGTERM end it cleanly (exit 0).
#include <poll.h>
#include <signal.h>
#include <sys/signalfd.h>
#include <sys/timerfd.h>
#include <time.h>
#include <unistd.h>

#include <array>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>

#include "SocketCanPort.hpp"
#include "board/fields.hpp"
#include "canopen/Node.hpp"
#include "core/MessageBoard.hpp"
#include "core/MessageBoardUser.hpp"
#include "core/Scheduler.hpp"

namespace {

using board::FieldId;

constexpr float kAdcFullScale = 4095.0F;    // the photodiode's 12-bit ADC at full brightness
constexpr float kPwmFullScale = 10000.0F;   // lamp_pwm at 100 % duty (the table's 0.01 % unit)

// The hardware registers: the node writes the photodiode's raw reading as the RPDO brings it,
// the sensor drains it in its update(); the actuator leaves the PWM the TPDO carries.
struct LampRegisters {
  std::int32_t photodiode_adc = 0;
  std::int32_t lamp_pwm = 0;
};

class LightSensor final : public core::Sensor {
 public:
  LightSensor(core::MessageBoard& board, const LampRegisters& registers)
      : Sensor(board, "light_sensor", {.writes = {FieldId::light_level}}), registers_{registers} {}
  void update() override { boardSet(FieldId::light_level, static_cast<float>(registers_.photodiode_adc) / kAdcFullScale); }

 private:
  const LampRegisters& registers_;
};

// Open loop: the lamp's light in steady state is its duty, so the setpoint is the duty.
class LampDriver final : public core::Actuator {
 public:
  LampDriver(core::MessageBoard& board, LampRegisters& registers)
      : Actuator(board, "lamp_driver", {.reads = {FieldId::light_setpoint}}), registers_{registers} {}
  void update() override {
    const float duty = boardGet(FieldId::light_setpoint);
    registers_.lamp_pwm = static_cast<std::int32_t>(duty * kPwmFullScale + 0.5F);
  }

 private:
  LampRegisters& registers_;
};

// The node's write access to the board: the owner of the bus-writable fields.
class BusWriter final : public core::ExternalWriter {
 public:
  explicit BusWriter(core::MessageBoard& board)
      : ExternalWriter(board, "canopen_node", {.writes = core::kBusWritableFields}) {}
  core::SetResult write(FieldId id, float value) { return boardSet(id, value); }
};

struct Lamp {
  core::MessageBoard board;
  core::Scheduler scheduler{board};
  LampRegisters registers;
  BusWriter bus_writer{board};
  LightSensor sensor{board, registers};
  LampDriver driver{board, registers};

  bool start() {
    if (!scheduler.add(bus_writer) || !scheduler.add(sensor) || !scheduler.add(driver)) return false;
    const core::StartupStatus status = scheduler.start();
    if (!status.ok()) std::fprintf(stderr, "lamp-firmware: start-up error: %s\n", status.message().c_str());
    return status.ok();
  }
};

class LampFields final : public co::FieldAccess {
 public:
  explicit LampFields(Lamp& lamp) : lamp_{lamp} {}
  float read(FieldId id) override { return lamp_.board.get(id); }
  co::WriteResult write(FieldId id, float value) override {
    return lamp_.bus_writer.write(id, value) == core::SetResult::Ok ? co::WriteResult::Accepted
                                                                    : co::WriteResult::Refused;
  }

 private:
  Lamp& lamp_;
};

class LampIo final : public co::HilIo {
 public:
  explicit LampIo(LampRegisters& registers) : registers_{registers} {}
  void write_input(board::HilInputId id, std::int32_t raw) override {
    if (id == board::HilInputId::photodiode_adc) registers_.photodiode_adc = raw;
  }
  std::int32_t read_output(board::HilOutputId id) override {
    return id == board::HilOutputId::lamp_pwm ? registers_.lamp_pwm : 0;
  }

 private:
  LampRegisters& registers_;
};

class NoStorage final : public co::ParameterStorage {
 public:
  bool save(std::span<const std::byte>) override { return false; }
  std::size_t load(std::span<std::byte>) override { return 0; }
};

std::uint32_t now_us() {
  timespec now{};
  clock_gettime(CLOCK_MONOTONIC, &now);
  return static_cast<std::uint32_t>(static_cast<std::uint64_t>(now.tv_sec) * 1'000'000U +
                                    static_cast<std::uint64_t>(now.tv_nsec) / 1000U);
}

struct Options {
  std::string can = "vcan0";
  int node_id = board::kNode.default_node_id;
  bool lockstep = true;
  std::uint32_t period_us = 1000;
};

// The rig's command line; anything else: a one-line error, exit 2.
std::optional<Options> parse(int argc, char** argv) {
  Options options;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string option = argv[i];
    const std::string value = argv[i + 1];
    if (option == "--can") {
      options.can = value;
    } else if (option == "--node-id") {
      options.node_id = static_cast<int>(std::strtol(value.c_str(), nullptr, 0));
    } else if (option == "--mode" && (value == "lockstep" || value == "free")) {
      options.lockstep = value == "lockstep";
    } else if (option == "--period-us") {
      options.period_us = static_cast<std::uint32_t>(std::strtoul(value.c_str(), nullptr, 0));
    } else if (option == "--image-dir") {
      // no program download on the lamp
    } else {
      std::fprintf(stderr, "lamp-firmware: unknown option or value: %s %s\n", option.c_str(), value.c_str());
      return std::nullopt;
    }
  }
  if (argc % 2 == 0 || options.node_id < 1 || options.node_id > 127 || options.period_us == 0) {
    std::fprintf(stderr, "lamp-firmware: usage: --can CHANNEL --node-id 1..127 --mode lockstep|free --period-us P\n");
    return std::nullopt;
  }
  return options;
}

}  // namespace

int main(int argc, char** argv) {
  const std::optional<Options> options = parse(argc, argv);
  if (!options) return 2;
  Lamp lamp;
  if (!lamp.start()) return 1;
  linuxhw::SocketCanPort port;
  if (std::string error; !port.open(options->can, error)) {
    std::fprintf(stderr, "lamp-firmware: %s\n", error.c_str());
    return 1;
  }
  LampFields fields{lamp};
  LampIo io{lamp.registers};
  NoStorage storage;
  co::Node node{static_cast<std::uint8_t>(options->node_id), port, fields, io, storage};
  node.set_acceptance_listener(&port);
  node.set_timeout_clock(options->lockstep ? co::TimeoutClock::ControlCycles : co::TimeoutClock::WallTime);

  sigset_t stop;
  sigemptyset(&stop);
  sigaddset(&stop, SIGINT);
  sigaddset(&stop, SIGTERM);
  sigprocmask(SIG_BLOCK, &stop, nullptr);
  const int signal_fd = signalfd(-1, &stop, SFD_NONBLOCK | SFD_CLOEXEC);
  int timer_fd = -1;
  if (!options->lockstep) {
    timer_fd = timerfd_create(CLOCK_MONOTONIC, TFD_NONBLOCK | TFD_CLOEXEC);
    itimerspec spec{};
    clock_gettime(CLOCK_MONOTONIC, &spec.it_value);
    spec.it_interval.tv_sec = options->period_us / 1'000'000U;
    spec.it_interval.tv_nsec = static_cast<long>(options->period_us % 1'000'000U) * 1000;
    timerfd_settime(timer_fd, TFD_TIMER_ABSTIME, &spec, nullptr);
  }

  node.start(now_us());
  std::fprintf(stderr, "lamp-firmware: node %d on %s, %s, period %u us\n", node.node_id(), options->can.c_str(),
               options->lockstep ? "lockstep" : "free-running", options->period_us);
  std::uint32_t cycle = 0;
  bool running = true;
  while (running) {
    std::array<pollfd, 3> fds{{{port.fd(), POLLIN, 0}, {signal_fd, POLLIN, 0}, {timer_fd, POLLIN, 0}}};
    ::poll(fds.data(), timer_fd >= 0 ? 3 : 2, 1);
    if ((fds[1].revents & POLLIN) != 0) running = false;
    if (timer_fd >= 0 && (fds[2].revents & POLLIN) != 0) {
      std::uint64_t expirations = 0;
      if (::read(timer_fd, &expirations, sizeof(expirations)) == sizeof(expirations)) {
        lamp.scheduler.run_cycle(++cycle);
      }
    }
    co::CanFrame frame;
    while (port.receive(frame) == co::ReceiveResult::Received) {
      if (node.process(frame, now_us()).sync) {
        if (options->lockstep) {
          node.advance_control_time(options->period_us);
          lamp.scheduler.run_cycle(++cycle);
        }
        node.transmit_synchronous_pdos(now_us());
      }
    }
    node.poll(now_us());
  }
  std::fprintf(stderr, "lamp-firmware: stopped after %u cycles\n", cycle);
  return 0;
}
