// A hardware counter input (quadrature encoder timer): the latest 16-bit count,
// wrapping at 65536, and whether a new sample arrived since the previous read.
#pragma once

#include <cstdint>

namespace joint {

struct CounterSample {
  std::uint16_t counts;  // the newest raw counter value (0 before any sample)
  bool fresh;            // true if a sample arrived since the previous read()
};

class CounterInput {
 public:
  virtual ~CounterInput() = default;
  // Consumes the freshness: a second read() without a new sample is not fresh.
  virtual CounterSample read() = 0;

 protected:
  CounterInput() = default;
  CounterInput(const CounterInput&) = default;
  CounterInput& operator=(const CounterInput&) = default;
};

}  // namespace joint
