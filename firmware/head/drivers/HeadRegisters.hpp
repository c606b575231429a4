// The head's drivers on the hardware-in-the-loop rig: raw values arrive in CAN frames (the
// node's HIL inputs) and leave in CAN frames (its HIL outputs), so every driver is an
// intermediate register. The receive path calls write_input() (never the board: the seed's
// interrupt policy); the transmit path calls read_output() after each cycle.
//
// Threading as joint::HilRegisters: one producer and one consumer per input register,
// lock-free; outputs are single atomics. No heap.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>

#include "board/fields.hpp"
#include "core/LatestValueRegister.hpp"
#include "head/drivers/HeadDrivers.hpp"

namespace head {

class HeadRegisters {
 public:
  HeadRegisters() = default;
  // drivers() hands out references into this object: it never moves.
  HeadRegisters(const HeadRegisters&) = delete;
  HeadRegisters& operator=(const HeadRegisters&) = delete;

  // --- receive path: one HIL input object as the hardware gives it (already range-checked by
  // the node against its type) ----------------------------------------------------------------
  void write_input(board::HilInputId id, std::int32_t raw) {
    switch (id) {
      case board::HilInputId::accel_x_counts: imu_.axes_[0].write(static_cast<std::int16_t>(raw)); break;
      case board::HilInputId::accel_y_counts: imu_.axes_[1].write(static_cast<std::int16_t>(raw)); break;
      case board::HilInputId::accel_z_counts: imu_.axes_[2].write(static_cast<std::int16_t>(raw)); break;
      case board::HilInputId::gyro_x_counts: imu_.axes_[3].write(static_cast<std::int16_t>(raw)); break;
      case board::HilInputId::gyro_y_counts: imu_.axes_[4].write(static_cast<std::int16_t>(raw)); break;
      case board::HilInputId::gyro_z_counts: imu_.axes_[5].write(static_cast<std::int16_t>(raw)); break;
      case board::HilInputId::rail_current_adc: rail_current_.register_.write(static_cast<std::uint16_t>(raw)); break;
      case board::HilInputId::battery_adc: battery_.register_.write(static_cast<std::uint16_t>(raw)); break;
      case board::HilInputId::kCount: break;
    }
  }

  // --- transmit path: what the actuators last commanded (0 before the first cycle) ----------
  std::int32_t read_output(board::HilOutputId id) const {
    switch (id) {
      case board::HilOutputId::led_red_pwm: return led_.red_.load(std::memory_order_acquire);
      case board::HilOutputId::led_green_pwm: return led_.green_.load(std::memory_order_acquire);
      case board::HilOutputId::led_blue_pwm: return led_.blue_.load(std::memory_order_acquire);
      case board::HilOutputId::rail_switch: return rail_switch_.closed_.load(std::memory_order_acquire) ? 1 : 0;
      case board::HilOutputId::kCount: break;
    }
    return 0;
  }

  // The driver interfaces the components use, all backed by this object.
  HeadDrivers drivers() { return HeadDrivers{imu_, rail_current_, battery_, led_, rail_switch_}; }

 private:
  // Six axis registers (accel x, y, z, gyro x, y, z); a sample is fresh when any axis is.
  class Imu final : public ImuInput {
   public:
    ImuSample read() override {
      ImuSample sample;
      for (std::size_t axis = 0; axis < 3; ++axis) {
        const auto accel = axes_[axis].read();
        const auto gyro = axes_[axis + 3].read();
        sample.accel_counts[axis] = accel.value;
        sample.gyro_counts[axis] = gyro.value;
        sample.fresh = sample.fresh || accel.fresh || gyro.fresh;
      }
      return sample;
    }
    std::array<core::LatestValueRegister<std::int16_t>, 6> axes_;
  };

  class Milli final : public MilliInput {
   public:
    MilliSample read() override {
      const auto reading = register_.read();
      return MilliSample{reading.value, reading.fresh};
    }
    core::LatestValueRegister<std::uint16_t> register_;
  };

  class Led final : public LedPwmOutput {
   public:
    void write(std::uint8_t red, std::uint8_t green, std::uint8_t blue) override {
      red_.store(red, std::memory_order_release);
      green_.store(green, std::memory_order_release);
      blue_.store(blue, std::memory_order_release);
    }
    std::atomic<std::uint8_t> red_{0};
    std::atomic<std::uint8_t> green_{0};
    std::atomic<std::uint8_t> blue_{0};
  };

  class RailSwitch final : public RailSwitchOutput {
   public:
    void write(bool closed) override { closed_.store(closed, std::memory_order_release); }
    std::atomic<bool> closed_{false};
  };

  Imu imu_;
  Milli rail_current_;
  Milli battery_;
  Led led_;
  RailSwitch rail_switch_;
};

}  // namespace head
