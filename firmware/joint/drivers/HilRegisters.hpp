// The demo joint's drivers on the hardware-in-the-loop rig: raw values arrive
// in CAN frames and leave in CAN frames, so every driver is an intermediate
// register. The platform's receive path calls the write_* side (never the
// board, per the seed's interrupt policy); its transmit path reads the *_raw()
// side after each cycle. The components see only the driver interfaces,
// through drivers().
//
// Threading: one producer (receive path) and one consumer (control cycle) per
// input register, lock-free; outputs are single atomics. No heap.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>

#include "board/fields.hpp"
#include "core/LatestValueRegister.hpp"
#include "core/SampleBuffer.hpp"
#include "joint/drivers/JointDrivers.hpp"

namespace joint {

class HilRegisters {
 public:
  // Thermistor conversions buffered between two cycles; more are dropped and counted.
  static constexpr std::size_t kThermistorSampleCapacity = 16;

  HilRegisters() = default;
  // drivers() hands out references into this object: it never moves.
  HilRegisters(const HilRegisters&) = delete;
  HilRegisters& operator=(const HilRegisters&) = delete;

  // --- receive path: raw inputs as the hardware gives them ---------------
  void write_motor_encoder(std::uint16_t counts) { motor_encoder_.register_.write(counts); }
  void write_output_encoder(std::uint16_t counts) { output_encoder_.register_.write(counts); }
  // false: the buffer held kThermistorSampleCapacity undrained samples, this one was dropped.
  bool write_thermistor_adc(std::uint16_t adc_counts) { return thermistor_.buffer_.push(adc_counts); }
  void write_motor_current(std::int16_t milliamps) { motor_current_.register_.write(milliamps); }
  // The node's heartbeat consumer (co::HeartbeatListener): `lost_entries` watched heartbeats
  // lost now; `event`: one was just lost.
  void write_heartbeat_status(std::uint8_t lost_entries, bool event) {
    heartbeat_.write(lost_entries, event);
  }

  // The same, by the table's object: what the CANopen node's HIL I/O view calls (the platform's
  // views of a board's registers, NodeOnRegisters.hpp).
  void write_input(board::HilInputId id, std::int32_t raw) {
    switch (id) {
      case board::HilInputId::motor_encoder_counts: write_motor_encoder(static_cast<std::uint16_t>(raw)); break;
      case board::HilInputId::output_encoder_counts: write_output_encoder(static_cast<std::uint16_t>(raw)); break;
      case board::HilInputId::thermistor_adc: write_thermistor_adc(static_cast<std::uint16_t>(raw)); break;
      case board::HilInputId::motor_current_adc: write_motor_current(static_cast<std::int16_t>(raw)); break;
      case board::HilInputId::kCount: break;
    }
  }
  void heartbeat_status(std::uint8_t lost_entries, bool event) { write_heartbeat_status(lost_entries, event); }

  // --- transmit path: what the actuators last commanded -------------------
  // -10000..10000 (0.01 % of bus voltage); 0 before the first cycle.
  std::int16_t motor_duty_raw() const { return motor_duty_.value_.load(std::memory_order_acquire); }
  // 0 off, 1 on, 2 slow blink, 3 fast blink; 0 before the first cycle.
  std::uint8_t led_pattern_raw() const { return status_led_.value_.load(std::memory_order_acquire); }

  // The same, by the table's object.
  std::int32_t read_output(board::HilOutputId id) const {
    switch (id) {
      case board::HilOutputId::motor_duty: return motor_duty_raw();
      case board::HilOutputId::led_pattern: return led_pattern_raw();
      case board::HilOutputId::kCount: break;
    }
    return 0;
  }

  // Thermistor samples dropped because the control cycle did not drain them in time.
  std::uint32_t thermistor_overflows() const { return thermistor_.buffer_.overflow_count(); }

  // The driver interfaces the components use, all backed by this object.
  JointDrivers drivers() {
    return JointDrivers{motor_encoder_, output_encoder_, thermistor_, motor_current_,
                        motor_duty_,    status_led_,     heartbeat_};
  }

 private:
  class Counter final : public CounterInput {
   public:
    CounterSample read() override {
      const auto reading = register_.read();
      return CounterSample{reading.value, reading.fresh};
    }
    core::LatestValueRegister<std::uint16_t> register_;
  };

  class ThermistorAdc final : public AdcSampleInput {
   public:
    std::size_t drain(std::span<std::uint16_t> out) override { return buffer_.drain_into(out); }
    core::SampleBuffer<std::uint16_t, kThermistorSampleCapacity> buffer_;
  };

  class Current final : public CurrentInput {
   public:
    CurrentSample read() override {
      const auto reading = register_.read();
      return CurrentSample{reading.value, reading.fresh};
    }
    core::LatestValueRegister<std::int16_t> register_;
  };

  // Events are counted on the producer side, so the sensor sees a loss that ended before it
  // looked: the count moved.
  class Heartbeat final : public HeartbeatInput {
   public:
    // 32 bits in all, so the register is lock-free on a 32-bit microcontroller too (a Cortex-M
    // has no 64-bit atomics). The sensor only asks whether the count moved since it last looked,
    // once a cycle: 16 bits wrap after 65536 events, never between two looks.
    struct Status {
      std::uint16_t events;  // heartbeat events since construction (wraps)
      std::uint16_t lost_entries;
    };
    void write(std::uint8_t lost_entries, bool event) {
      if (event) ++events_;
      register_.write(Status{events_, lost_entries});
    }
    HeartbeatSample read() override {
      const Status status = register_.read().value;
      const bool new_event = status.events != seen_events_;
      seen_events_ = status.events;
      return HeartbeatSample{status.lost_entries != 0, new_event};
    }

   private:
    core::LatestValueRegister<Status> register_;
    std::uint16_t events_ = 0;       // producer-only
    std::uint16_t seen_events_ = 0;  // consumer-only
  };

  class Duty final : public DutyOutput {
   public:
    void write(std::int16_t duty_raw) override { value_.store(duty_raw, std::memory_order_release); }
    std::atomic<std::int16_t> value_{0};
  };

  class Led final : public LedOutput {
   public:
    void write(LedPattern pattern) override {
      value_.store(static_cast<std::uint8_t>(pattern), std::memory_order_release);
    }
    std::atomic<std::uint8_t> value_{0};
  };

  Counter motor_encoder_;
  Counter output_encoder_;
  ThermistorAdc thermistor_;
  Current motor_current_;
  Duty motor_duty_;
  Led status_led_;
  Heartbeat heartbeat_;
};

}  // namespace joint
