#include "joint/modules/SpringConstantRls.hpp"

#include <algorithm>

namespace joint {

SpringConstantRls::SpringConstantRls(const SpringConstantRlsConfig& config) : config_{config} { reset(0.0); }

void SpringConstantRls::reset(double initial_k) {
  k_ = initial_k;
  offset_ = 0.0;
  p_kk_ = config_.initial_covariance;
  p_ko_ = 0.0;
  p_oo_ = config_.initial_covariance;
  weight_ = 0.0;
  deflection_mean_ = 0.0;
  deflection_scatter_ = 0.0;
  torque_mean_ = 0.0;
  torque_scatter_ = 0.0;
  residual_squares_ = 0.0;
  samples_ = 0;
}

void SpringConstantRls::update(double deflection_rad, double torque_nm) {
  const double lambda = config_.forgetting_factor;
  // Regressor phi = (deflection, 1).
  const double p_phi_k = p_kk_ * deflection_rad + p_ko_;
  const double p_phi_o = p_ko_ * deflection_rad + p_oo_;
  const double denominator = lambda + deflection_rad * p_phi_k + p_phi_o;
  const double gain_k = p_phi_k / denominator;
  const double gain_o = p_phi_o / denominator;
  const double prediction_error = torque_nm - (k_ * deflection_rad + offset_);
  k_ += gain_k * prediction_error;
  offset_ += gain_o * prediction_error;
  // P = (P - K phi^T P) / lambda
  p_kk_ = (p_kk_ - gain_k * p_phi_k) / lambda;
  p_ko_ = (p_ko_ - gain_k * p_phi_o) / lambda;
  p_oo_ = (p_oo_ - gain_o * p_phi_o) / lambda;
  const double trace = p_kk_ + p_oo_;
  if (trace > config_.max_covariance_trace) {
    const double scale = config_.max_covariance_trace / trace;
    p_kk_ *= scale;
    p_ko_ *= scale;
    p_oo_ *= scale;
  }

  // Weighted mean and scatter (West's incremental form, with forgetting).
  weight_ = lambda * weight_ + 1.0;
  const double deflection_step = deflection_rad - deflection_mean_;
  deflection_mean_ += deflection_step / weight_;
  deflection_scatter_ = lambda * deflection_scatter_ + deflection_step * (deflection_rad - deflection_mean_);
  const double torque_step = torque_nm - torque_mean_;
  torque_mean_ += torque_step / weight_;
  torque_scatter_ = lambda * torque_scatter_ + torque_step * (torque_nm - torque_mean_);
  const double residual = torque_nm - (k_ * deflection_rad + offset_);
  residual_squares_ = lambda * residual_squares_ + residual * residual;
  if (samples_ < UINT32_MAX) {
    ++samples_;
  }
}

double SpringConstantRls::confidence() const {
  if (weight_ <= 0.0 || torque_scatter_ <= 0.0) {
    return 0.0;
  }
  const double deflection_variance = deflection_scatter_ / weight_;
  const double scale_squared = config_.excitation_scale_rad * config_.excitation_scale_rad;
  const double excitation = deflection_variance / (deflection_variance + scale_squared);
  const double fit = std::clamp(1.0 - residual_squares_ / torque_scatter_, 0.0, 1.0);
  return std::clamp(excitation * fit, 0.0, 1.0);
}

}  // namespace joint
