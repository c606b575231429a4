// The NTC beta model: R = R25 * exp(B * (1/T - 1/298.15 K)), solved for T.
#pragma once

namespace joint {

inline constexpr float kKelvinAtZeroCelsius = 273.15F;
inline constexpr float kNtcReferenceTemperatureK = 298.15F;  // 25 degC, where R = R25

// The temperature [degC] of an NTC with `resistance_ohm` (> 0).
float ntc_temperature_c(float resistance_ohm, float r25_ohm, float beta_k);

}  // namespace joint
