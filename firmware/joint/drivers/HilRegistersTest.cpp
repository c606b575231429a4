#include "joint/drivers/HilRegisters.hpp"

#include <gtest/gtest.h>

#include <array>

namespace joint {
namespace {

TEST(HilRegisters, HandsTheNewestCounterValueOnceAsFresh) {
  HilRegisters registers;
  CounterInput& encoder = registers.drivers().motor_encoder;
  EXPECT_FALSE(encoder.read().fresh);
  registers.write_motor_encoder(10);
  registers.write_motor_encoder(20);
  const CounterSample sample = encoder.read();
  EXPECT_EQ(sample.counts, 20);
  EXPECT_TRUE(sample.fresh);
  EXPECT_FALSE(encoder.read().fresh);
  // The two encoders are separate registers.
  EXPECT_FALSE(registers.drivers().output_encoder.read().fresh);
}

TEST(HilRegisters, BuffersThermistorSamplesAndCountsOverflows) {
  HilRegisters registers;
  for (std::size_t i = 0; i < HilRegisters::kThermistorSampleCapacity; ++i) {
    ASSERT_TRUE(registers.write_thermistor_adc(static_cast<std::uint16_t>(1000 + i)));
  }
  EXPECT_FALSE(registers.write_thermistor_adc(9));
  EXPECT_EQ(registers.thermistor_overflows(), 1U);
  std::array<std::uint16_t, 32> out{};
  EXPECT_EQ(registers.drivers().thermistor_adc.drain(out), HilRegisters::kThermistorSampleCapacity);
  EXPECT_EQ(out[0], 1000);
  EXPECT_EQ(registers.drivers().thermistor_adc.drain(out), 0U);
}

TEST(HilRegisters, PassesCurrentAndOutputsThrough) {
  HilRegisters registers;
  // Before the first cycle the outputs read 0: the motor off, the LED off.
  EXPECT_EQ(registers.read_output(board::HilOutputId::motor_duty), 0);
  EXPECT_EQ(registers.read_output(board::HilOutputId::led_pattern), 0);
  registers.write_motor_current(-1234);
  const CurrentSample current = registers.drivers().motor_current.read();
  EXPECT_EQ(current.milliamps, -1234);
  EXPECT_TRUE(current.fresh);
  registers.drivers().motor_duty.write(-10000);
  registers.drivers().status_led.write(LedPattern::FastBlink);
  EXPECT_EQ(registers.motor_duty_raw(), -10000);
  EXPECT_EQ(registers.led_pattern_raw(), 3);
}

TEST(HilRegisters, ReportsAHeartbeatLossUntilItEndsAndAnEventOnceEvenIfItEndedUnread) {
  HilRegisters registers;
  HeartbeatInput& heartbeat = registers.drivers().heartbeat;
  EXPECT_FALSE(heartbeat.read().lost_now);
  registers.write_heartbeat_status(1, true);
  HeartbeatSample sample = heartbeat.read();
  EXPECT_TRUE(sample.lost_now && sample.lost_since_last_read);
  sample = heartbeat.read();
  EXPECT_TRUE(sample.lost_now) << "still lost";
  EXPECT_FALSE(sample.lost_since_last_read) << "the event was consumed";
  // Lost and back between two reads: no longer lost, but the event still shows.
  registers.write_heartbeat_status(0, false);
  registers.write_heartbeat_status(1, true);
  registers.write_heartbeat_status(0, false);
  sample = heartbeat.read();
  EXPECT_FALSE(sample.lost_now);
  EXPECT_TRUE(sample.lost_since_last_read);
  EXPECT_FALSE(heartbeat.read().lost_since_last_read);
}

}  // namespace
}  // namespace joint
