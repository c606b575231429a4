// Turns successive readings of a 16-bit wrapping hardware counter into a
// continuous count. The counter starts at 0 at power-up, so the first reading
// is taken as a signed step from 0 (65535 means -1). Readings must come often
// enough that the shaft moves less than half a wrap (32768 counts) between
// them: at 1 kHz and 4096 counts/rev that is 8 revolutions per cycle.
#pragma once

#include <cstdint>

namespace joint {

class EncoderUnwrapper {
 public:
  // Takes one raw reading; returns the continuous count.
  std::int64_t update(std::uint16_t raw_counts) {
    const auto step = static_cast<std::int16_t>(static_cast<std::uint16_t>(raw_counts - previous_raw_));
    counts_ += step;
    previous_raw_ = raw_counts;
    return counts_;
  }

  std::int64_t counts() const { return counts_; }

 private:
  std::uint16_t previous_raw_ = 0;
  std::int64_t counts_ = 0;
};

// The angle of a continuous count [rad].
float counts_to_rad(std::int64_t counts, float counts_per_rev);

}  // namespace joint
