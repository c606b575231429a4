#include "joint/modules/SpringConstantRls.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>

namespace joint {
namespace {

TEST(SpringConstantRls, ConvergesToAKnownStiffnessWithinFivePercent) {
  // True k = 80 N*m/rad, start from the nominal 50; a torque offset of 0.3 N*m and
  // noise of 0.05 N*m as from current-sensor offset and quantisation.
  constexpr double kTrueK = 80.0;
  SpringConstantRls rls;
  rls.reset(50.0);
  std::mt19937 generator{12345};
  std::normal_distribution<double> noise{0.0, 0.05};
  for (int n = 0; n < 5000; ++n) {
    const double deflection_rad = 0.05 * std::sin(2.0 * std::numbers::pi * 0.5 * n * 0.001);
    rls.update(deflection_rad, kTrueK * deflection_rad + 0.3 + noise(generator));
  }
  EXPECT_NEAR(rls.spring_constant(), kTrueK, 0.05 * kTrueK);
  EXPECT_NEAR(rls.offset_nm(), 0.3, 0.05);
  EXPECT_GT(rls.confidence(), 0.8);
}

// A reset forgets everything learnt: on the same samples a reset estimator and a new one agree
// exactly (its covariance starts again from the configured prior on both parameters).
TEST(SpringConstantRls, AResetEstimatorIsANewOne) {
  const auto feed = [](SpringConstantRls& rls, double k, double offset, int samples) {
    for (int n = 0; n < samples; ++n) {
      const double deflection_rad = 0.05 * std::sin(2.0 * std::numbers::pi * 0.5 * n * 0.001);
      rls.update(deflection_rad, k * deflection_rad + offset);
    }
  };
  SpringConstantRls used;
  used.reset(50.0);
  feed(used, 80.0, 0.3, 5000);
  used.reset(50.0);
  SpringConstantRls fresh;
  fresh.reset(50.0);
  feed(used, 60.0, -0.5, 300);
  feed(fresh, 60.0, -0.5, 300);
  EXPECT_DOUBLE_EQ(used.spring_constant(), fresh.spring_constant());
  EXPECT_DOUBLE_EQ(used.offset_nm(), fresh.offset_nm());
  EXPECT_DOUBLE_EQ(used.confidence(), fresh.confidence());
}

TEST(SpringConstantRls, HasNoConfidenceWithoutExcitation) {
  // Constant deflection: k and the offset cannot be told apart.
  SpringConstantRls rls;
  rls.reset(50.0);
  std::mt19937 generator{7};
  std::normal_distribution<double> noise{0.0, 0.05};
  for (int n = 0; n < 5000; ++n) {
    rls.update(0.02, 80.0 * 0.02 + noise(generator));
  }
  EXPECT_LT(rls.confidence(), 0.05);
}

TEST(SpringConstantRls, LosesConfidenceWhenTheDataDoNotFitALine) {
  // Torque unrelated to deflection (pure noise as large as the signal would be).
  SpringConstantRls rls;
  rls.reset(50.0);
  std::mt19937 generator{3};
  std::normal_distribution<double> noise{0.0, 2.0};
  for (int n = 0; n < 5000; ++n) {
    const double deflection_rad = 0.05 * std::sin(2.0 * std::numbers::pi * 0.5 * n * 0.001);
    rls.update(deflection_rad, noise(generator));
  }
  EXPECT_LT(rls.confidence(), 0.2);
}

// Two hours of samples at 1 kHz, with a long stretch without
// excitation in the middle (a joint turning at constant speed). The sums are
// forgetting (bounded by 1 / (1 - lambda)), the covariance is capped, the
// sample count saturates: after 7.2 million samples the estimator is as good
// as after five thousand, and it still follows a change of the spring.
TEST(SpringConstantRls, StaysAccurateAndResponsiveAfterTwoHoursOfSamples) {
  SpringConstantRls rls;
  rls.reset(50.0);
  std::mt19937 generator{20};
  std::normal_distribution<double> noise{0.0, 0.05};
  constexpr int kTwoHours = 7'200'000;
  double true_k = 80.0;
  for (int n = 0; n < kTwoHours; ++n) {
    const bool excited = n < 1'000'000 || n >= 6'000'000;
    if (n == 7'000'000) true_k = 60.0;  // the spring changes in the last 200 s
    const double deflection_rad =
        excited ? 0.05 * std::sin(2.0 * std::numbers::pi * 0.5 * (n % 2000) * 0.001) : 0.02;
    rls.update(deflection_rad, true_k * deflection_rad + 0.3 + noise(generator));
    if (n == 5'999'999) {
      ASSERT_TRUE(std::isfinite(rls.spring_constant())) << "after 5e6 samples without excitation";
      EXPECT_LT(rls.confidence(), 0.05);
    }
  }
  EXPECT_NEAR(rls.spring_constant(), 60.0, 0.01 * 60.0);
  EXPECT_NEAR(rls.offset_nm(), 0.3, 0.05);
  EXPECT_GT(rls.confidence(), 0.9);
  EXPECT_EQ(rls.samples(), static_cast<std::uint32_t>(kTwoHours));
}

}  // namespace
}  // namespace joint
