// Online estimate of a spring's stiffness k from pairs (deflection, torque),
// independent of the board: recursive least squares on
//     torque = k * deflection + offset
// with exponential forgetting (old data fades with factor lambda per sample,
// an effective window of 1 / (1 - lambda) samples). The offset absorbs a
// current-sensor offset and friction bias, so k comes from how torque changes
// with deflection, which needs the deflection to vary.
//
// Confidence (0..1) = excitation * fit, over the same forgetting window:
//   excitation = var(deflection) / (var(deflection) + excitation_scale^2):
//     0 when the deflection does not vary (k is then not observable), 1/2 at
//     a standard deviation of excitation_scale_rad;
//   fit = 1 - var(residual) / var(torque), the coefficient of determination:
//     how much of the torque's variation the line explains.
#pragma once

#include <cstdint>

namespace joint {

struct SpringConstantRlsConfig {
  double forgetting_factor = 0.999;     // lambda, (0, 1]
  double initial_covariance = 1.0e4;    // P(0) on both parameters: weak trust in the start value
  double max_covariance_trace = 1.0e6;  // bounds P while excitation is poor (covariance wind-up)
  double excitation_scale_rad = 0.01;
};

class SpringConstantRls {
 public:
  explicit SpringConstantRls(const SpringConstantRlsConfig& config = {});

  // Forgets all data; the estimate starts from initial_k, with no confidence.
  void reset(double initial_k);

  void update(double deflection_rad, double torque_nm);

  double spring_constant() const { return k_; }
  double offset_nm() const { return offset_; }
  double confidence() const;
  std::uint32_t samples() const { return samples_; }

 private:
  SpringConstantRlsConfig config_;
  double k_ = 0.0;
  double offset_ = 0.0;
  // Covariance P (symmetric 2x2) of (k, offset).
  double p_kk_ = 0.0;
  double p_ko_ = 0.0;
  double p_oo_ = 0.0;
  // Exponentially weighted statistics over the forgetting window.
  double weight_ = 0.0;
  double deflection_mean_ = 0.0;
  double deflection_scatter_ = 0.0;  // weighted sum of squared deviations
  double torque_mean_ = 0.0;
  double torque_scatter_ = 0.0;
  double residual_squares_ = 0.0;
  std::uint32_t samples_ = 0;
};

}  // namespace joint
