#include "joint/virtual_sensors/NtcThermistor.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "joint/sensors/ThermistorDivider.hpp"

namespace joint {
namespace {

constexpr float kR25Ohm = 10000.0F;  // board.toml defaults: ntc_r25_ohm, ntc_beta_k
constexpr float kBetaK = 3950.0F;

TEST(NtcThermistor, GivesTwentyFiveDegreesAtR25) {
  EXPECT_NEAR(ntc_temperature_c(kR25Ohm, kR25Ohm, kBetaK), 25.0F, 1e-3F);
}

TEST(NtcThermistor, MatchesTheTableExampleThroughTheDivider) {
  // board.toml: adc = round(4095 * R / (R + 10k)); at 25 degC R = R25, adc = round(2047.5) = 2048.
  const float resistance_ohm = *thermistor_resistance_ohm(2048.0F);
  EXPECT_NEAR(ntc_temperature_c(resistance_ohm, kR25Ohm, kBetaK), 25.0F, 0.05F);
}

TEST(NtcThermistor, InvertsTheBetaModelWhenHot) {
  // R(100 degC) = R25 * exp(B * (1/373.15 - 1/298.15)) = 697.5 ohm.
  const float resistance_ohm = kR25Ohm * std::exp(kBetaK * (1.0F / 373.15F - 1.0F / 298.15F));
  EXPECT_NEAR(resistance_ohm, 697.5F, 0.5F);
  EXPECT_NEAR(ntc_temperature_c(resistance_ohm, kR25Ohm, kBetaK), 100.0F, 0.01F);
}

}  // namespace
}  // namespace joint
