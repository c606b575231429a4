// The motor current ADC: signed, 1 count = 1 mA.
#pragma once

#include <cstdint>

namespace joint {

struct CurrentSample {
  std::int16_t milliamps;  // the newest reading (0 before any sample)
  bool fresh;              // true if a sample arrived since the previous read()
};

class CurrentInput {
 public:
  virtual ~CurrentInput() = default;
  // Consumes the freshness: a second read() without a new sample is not fresh.
  virtual CurrentSample read() = 0;

 protected:
  CurrentInput() = default;
  CurrentInput(const CurrentInput&) = default;
  CurrentInput& operator=(const CurrentInput&) = default;
};

}  // namespace joint
