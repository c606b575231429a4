// Spring twist between gearbox output and load:
//   spring_deflection = motor angle / gear_ratio - output angle,
// computed from the two encoders' continuous counts (unwrapped here from
// motor_encoder_raw and output_encoder_raw), not from the float angle fields:
// those two angles grow without bound while their difference stays small, so
// a difference of floats loses the deflection in their rounding (0.03 rad,
// 1.5 N*m of joint torque, after two hours at full speed). The counts are
// exact integers and the difference is taken in double, which keeps it within
// 2^-52 of the angle turned (1e-7 rad after a year at full speed).
// Written only when both encoders gave a sample this cycle.
#pragma once

#include <cstdint>

#include "core/MessageBoardUser.hpp"
#include "joint/sensors/EncoderUnwrapper.hpp"

namespace joint {

struct EncoderResolution {
  double motor_counts_per_rev;
  double output_counts_per_rev;
  double gear_ratio;
};

// The deflection [rad] of continuous encoder counts.
float spring_deflection_rad(std::int64_t motor_counts, std::int64_t output_counts, const EncoderResolution& resolution);

class SpringDeflection final : public core::VirtualSensor {
 public:
  explicit SpringDeflection(core::MessageBoard& board);

  void update() override;

 private:
  EncoderUnwrapper motor_counts_;
  EncoderUnwrapper output_counts_;
};

}  // namespace joint
