// The winding's thermal limit, independent of the board:
//   derate 1 below warning_c, linear down to 0 at limit_c;
//   at limit_c and above: over-temperature, derate 0, and it stays so until the
//   winding cools below limit_c - hysteresis_c (no chatter around the limit).
// Over-temperature is exactly "derate == 0": below the limit the linear part is
// strictly positive. The fault manager relies on that (see FaultManager.hpp).
#pragma once

namespace joint {

struct ThermalLimits {
  float warning_c;
  float limit_c;
  float hysteresis_c;
};

class ThermalDerate {
 public:
  // Returns the derate (0..1) for this temperature.
  float update(float temperature_c, const ThermalLimits& limits);

  bool over_temperature() const { return over_temperature_; }

 private:
  bool over_temperature_ = false;
};

}  // namespace joint
