// Velocity from successive positions: the difference quotient, smoothed by a
// first-order low-pass. The filter is discretised exactly (alpha = 1 -
// exp(-2 pi f_c dt)), so its step response is 1 - exp(-2 pi f_c t) at every
// sample whatever the cycle period, and a gap of several cycles is one step
// with a longer dt rather than a spike.
#pragma once

namespace joint {

class VelocityFilter {
 public:
  // One position sample `elapsed_s` after the previous one (ignored for the
  // first sample, which only sets the starting point). Returns the filtered
  // velocity [position unit / s]; 0 until the second sample.
  float update(float position, float elapsed_s, float cutoff_hz);

  float velocity() const { return velocity_; }
  bool has_velocity() const { return samples_ >= 2; }

 private:
  float previous_position_ = 0.0F;
  float velocity_ = 0.0F;
  int samples_ = 0;
};

}  // namespace joint
