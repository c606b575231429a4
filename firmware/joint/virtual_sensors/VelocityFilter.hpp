// Velocity from successive displacements: the difference quotient, smoothed by
// a first-order low-pass. The filter is discretised exactly (alpha = 1 -
// exp(-2 pi f_c dt)), so its step response is 1 - exp(-2 pi f_c t) at every
// sample whatever the cycle period, and a gap of several cycles is one step
// with a longer dt rather than a spike.
//
// It takes displacements, not positions: the caller computes them from exact
// quantities (encoder count steps), so the estimate does not degrade with the
// distance turned as a difference of two large float angles does.
#pragma once

namespace joint {

class VelocityFilter {
 public:
  // `displacement` [position unit] moved in the `elapsed_s` since the previous
  // sample (a sample with elapsed_s <= 0 is ignored). Returns the filtered
  // velocity [position unit / s]; 0 before the first sample.
  float update(float displacement, float elapsed_s, float cutoff_hz);

  float velocity() const { return velocity_; }
  bool has_velocity() const { return has_velocity_; }

 private:
  float velocity_ = 0.0F;
  bool has_velocity_ = false;
};

}  // namespace joint
