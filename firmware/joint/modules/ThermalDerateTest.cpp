#include "joint/modules/ThermalDerate.hpp"

#include <gtest/gtest.h>

namespace joint {
namespace {

constexpr ThermalLimits kLimits{.warning_c = 80.0F, .limit_c = 100.0F, .hysteresis_c = 10.0F};  // table defaults

TEST(ThermalDerate, IsOneBelowTheWarningAndFallsLinearlyToTheLimit) {
  ThermalDerate derate;
  EXPECT_FLOAT_EQ(derate.update(25.0F, kLimits), 1.0F);
  EXPECT_FLOAT_EQ(derate.update(80.0F, kLimits), 1.0F);
  EXPECT_FLOAT_EQ(derate.update(85.0F, kLimits), 0.75F);
  EXPECT_FLOAT_EQ(derate.update(90.0F, kLimits), 0.5F);
  EXPECT_NEAR(derate.update(99.9F, kLimits), 0.005F, 1e-4F);
  EXPECT_FALSE(derate.over_temperature());
  EXPECT_FLOAT_EQ(derate.update(100.0F, kLimits), 0.0F);
  EXPECT_TRUE(derate.over_temperature());
}

TEST(ThermalDerate, StaysOverTemperatureUntilCooledBelowLimitMinusHysteresis) {
  ThermalDerate derate;
  derate.update(101.0F, kLimits);
  ASSERT_TRUE(derate.over_temperature());
  EXPECT_FLOAT_EQ(derate.update(95.0F, kLimits), 0.0F);
  EXPECT_FLOAT_EQ(derate.update(90.0F, kLimits), 0.0F);  // exactly limit - hysteresis: not below
  EXPECT_TRUE(derate.over_temperature());
  EXPECT_FLOAT_EQ(derate.update(89.0F, kLimits), 0.55F);  // back on the curve
  EXPECT_FALSE(derate.over_temperature());
  EXPECT_FLOAT_EQ(derate.update(95.0F, kLimits), 0.25F);  // warming again below the limit: no fault
}

}  // namespace
}  // namespace joint
