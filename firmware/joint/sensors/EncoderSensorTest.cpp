#include "joint/sensors/EncoderSensor.hpp"

#include <gtest/gtest.h>

#include <numbers>

#include "core/Scheduler.hpp"
#include "joint/drivers/HilRegisters.hpp"

namespace joint {
namespace {

using board::FieldId;

class EncoderSensorTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(scheduler.add(encoder));
    const core::StartupStatus status = scheduler.start();
    ASSERT_TRUE(status) << status.message();
  }

  core::MessageBoard board;
  core::Scheduler scheduler{board};
  HilRegisters registers;
  EncoderSensor encoder{board, "output_encoder", registers.drivers().output_encoder, FieldId::output_position,
                        FieldId::output_encoder_raw, FieldId::output_encoder_counts_per_rev};
};

TEST_F(EncoderSensorTest, WritesTheUnwrappedOutputAngleAfterAWrap) {
  // Default 16384 counts per output revolution: 65536 + 4096 counts = 4.25 turns.
  std::uint32_t cycle = 1;
  for (std::uint32_t counts = 0; counts <= 65536 + 4096; counts += 4096) {
    registers.write_output_encoder(static_cast<std::uint16_t>(counts));
    scheduler.run_cycle(cycle++);
  }
  EXPECT_NEAR(board.get(FieldId::output_position), 4.25F * 2.0F * std::numbers::pi_v<float>, 1e-4F);
}

TEST_F(EncoderSensorTest, WritesNothingInACycleWithoutAFreshSample) {
  registers.write_output_encoder(100);
  scheduler.run_cycle(1);
  ASSERT_EQ(board.last_write_cycle(FieldId::output_position), 1U);
  scheduler.run_cycle(2);
  EXPECT_EQ(board.last_write_cycle(FieldId::output_position), 1U);
}

TEST_F(EncoderSensorTest, WritesTheRawCounterReadingBesideTheAngle) {
  registers.write_output_encoder(65535);
  scheduler.run_cycle(1);
  EXPECT_EQ(board.get(FieldId::output_encoder_raw), 65535.0F);
  EXPECT_EQ(board.last_write_cycle(FieldId::output_encoder_raw), 1U);
  registers.write_output_encoder(3);
  scheduler.run_cycle(2);
  EXPECT_EQ(board.get(FieldId::output_encoder_raw), 3.0F);  // wrapped, as the hardware counts
  EXPECT_NEAR(board.get(FieldId::output_position), 3.0F * 2.0F * std::numbers::pi_v<float> / 16384.0F, 1e-7F);
}

}  // namespace
}  // namespace joint
