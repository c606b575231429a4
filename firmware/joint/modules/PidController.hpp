// A PID controller with output limits and anti-windup, independent of the board.
//
// - The derivative acts on the measurement, not the error, so a setpoint step
//   gives no derivative kick.
// - Anti-windup by conditional integration: while the output is saturated, the
//   integrator only moves in the direction that leaves saturation; it is also
//   bounded by the output limit, so it can never hold more than full output.
// - The integrator stores duty (ki already applied), so a gain change moves
//   the output only through the new error, not by rescaling the history.
#pragma once

namespace joint {

struct PidGains {
  float kp = 0.0F;  // output per unit of error
  float ki = 0.0F;  // output per unit of error * s
  float kd = 0.0F;  // output per unit of error / s
};

class PidController {
 public:
  // One step: returns the output, within [-output_limit, output_limit]
  // (a negative limit counts as 0). dt_s > 0.
  float update(float setpoint, float measurement, float dt_s, const PidGains& gains, float output_limit);

  // Forgets the integrator and the previous measurement (used when the loop
  // is not in control, so it starts fresh when it is again).
  void reset();

  float integral() const { return integral_; }

 private:
  float integral_ = 0.0F;
  float previous_measurement_ = 0.0F;
  bool has_previous_measurement_ = false;
};

}  // namespace joint
