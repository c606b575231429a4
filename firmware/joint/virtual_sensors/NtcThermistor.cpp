#include "joint/virtual_sensors/NtcThermistor.hpp"

#include <cmath>

namespace joint {

float ntc_temperature_c(float resistance_ohm, float r25_ohm, float beta_k) {
  const float inverse_temperature_per_k = 1.0F / kNtcReferenceTemperatureK + std::log(resistance_ohm / r25_ohm) / beta_k;
  return 1.0F / inverse_temperature_per_k - kKelvinAtZeroCelsius;
}

}  // namespace joint
