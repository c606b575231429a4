#include "joint/sensors/ThermistorSensor.hpp"

#include <gtest/gtest.h>

#include "core/Scheduler.hpp"
#include "joint/drivers/HilRegisters.hpp"
#include "joint/sensors/ThermistorDivider.hpp"

namespace joint {
namespace {

using board::FieldId;

TEST(ThermistorDivider, InvertsTheDividerEquation) {
  // adc = 4095 * R / (R + 10k): R = 10k gives 2047.5, R = 30k gives 3071.25.
  EXPECT_FLOAT_EQ(*thermistor_resistance_ohm(2047.5F), 10000.0F);
  EXPECT_FLOAT_EQ(*thermistor_resistance_ohm(3071.25F), 30000.0F);
}

TEST(ThermistorDivider, HasNoResistanceForShortedOrOpenReadings) {
  EXPECT_FALSE(thermistor_resistance_ohm(0.0F));
  EXPECT_FALSE(thermistor_resistance_ohm(4095.0F));
}

class ThermistorSensorTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(scheduler.add(thermistor));
    const core::StartupStatus status = scheduler.start();
    ASSERT_TRUE(status) << status.message();
  }

  core::MessageBoard board;
  core::Scheduler scheduler{board};
  HilRegisters registers;
  ThermistorSensor thermistor{board, registers.drivers().thermistor_adc};
};

TEST_F(ThermistorSensorTest, AveragesTheSamplesThatArrivedSinceTheLastCycle) {
  for (const std::uint16_t adc : std::initializer_list<std::uint16_t>{2000, 2100, 2095}) {  // mean 2065
    ASSERT_TRUE(registers.write_thermistor_adc(adc));
  }
  scheduler.run_cycle(1);
  EXPECT_FLOAT_EQ(board.get(FieldId::thermistor_resistance), *thermistor_resistance_ohm(2065.0F));

  // The next cycle averages only its own sample.
  ASSERT_TRUE(registers.write_thermistor_adc(3000));
  scheduler.run_cycle(2);
  EXPECT_FLOAT_EQ(board.get(FieldId::thermistor_resistance), *thermistor_resistance_ohm(3000.0F));
}

TEST_F(ThermistorSensorTest, KeepsTheLastValueWithoutWritingWhenNoSampleArrived) {
  ASSERT_TRUE(registers.write_thermistor_adc(2048));
  scheduler.run_cycle(1);
  const float resistance = board.get(FieldId::thermistor_resistance);
  scheduler.run_cycle(2);
  EXPECT_EQ(board.get(FieldId::thermistor_resistance), resistance);
  EXPECT_EQ(board.last_write_cycle(FieldId::thermistor_resistance), 1U);
}

TEST_F(ThermistorSensorTest, LeavesOutShortedAndOpenReadings) {
  for (const std::uint16_t adc : std::initializer_list<std::uint16_t>{0, 2048, 4095}) {
    ASSERT_TRUE(registers.write_thermistor_adc(adc));
  }
  scheduler.run_cycle(1);
  EXPECT_FLOAT_EQ(board.get(FieldId::thermistor_resistance), *thermistor_resistance_ohm(2048.0F));

  // Only faulty readings: nothing written, the thermistor goes stale.
  ASSERT_TRUE(registers.write_thermistor_adc(4095));
  scheduler.run_cycle(2);
  EXPECT_EQ(board.last_write_cycle(FieldId::thermistor_resistance), 1U);
}

}  // namespace
}  // namespace joint
