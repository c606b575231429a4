// The intermediate registers with a real producer thread (standing in for the
// receive interrupt) and consumer thread (the control loop). Built with
// ThreadSanitizer, which reports any data race in them; the assertions check
// that no value is torn, reordered, lost unreported or invented.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdint>
#include <thread>

#include "core/LatestValueRegister.hpp"
#include "core/SampleBuffer.hpp"

namespace core {
namespace {

constexpr std::uint32_t kIterations = 1'000'000;

TEST(RegisterStressTest, LatestValueRegisterNeverReturnsTornOrOlderValues) {
  LatestValueRegister<std::uint32_t> latest;
  std::thread producer([&] {
    for (std::uint32_t i = 1; i <= kIterations; ++i) {
      latest.write(i);  // the i-th write carries the value i
    }
  });
  std::uint32_t previous = 0;
  std::uint32_t seen_fresh = 0;
  bool consistent = true;
  while (previous < kIterations && consistent) {
    const auto reading = latest.read();
    // Value and write count come from one snapshot; freshness means exactly "newer".
    consistent = reading.value >= previous && reading.fresh == (reading.value != previous) &&
                 reading.writes_since_last_read == reading.value - previous;
    seen_fresh += reading.fresh ? 1 : 0;
    previous = reading.value;
  }
  producer.join();
  EXPECT_TRUE(consistent) << "inconsistent reading after value " << previous;
  EXPECT_EQ(previous, kIterations);
  EXPECT_EQ(latest.write_count(), kIterations);
  EXPECT_GT(seen_fresh, 0u);
}

TEST(RegisterStressTest, SampleBufferDeliversEverySampleInOrderOrCountsItAsOverflow) {
  SampleBuffer<std::uint32_t, 64> buffer;
  std::atomic<bool> producer_done{false};
  std::uint32_t accepted = 0;
  std::thread producer([&] {
    for (std::uint32_t i = 1; i <= kIterations; ++i) {
      accepted += buffer.push(i) ? 1 : 0;
    }
    producer_done.store(true, std::memory_order_release);
  });
  std::uint32_t received = 0;
  std::uint32_t last = 0;
  bool in_order = true;
  const auto take = [&](std::uint32_t sample) {
    in_order = in_order && sample > last;
    last = sample;
    ++received;
  };
  while (!producer_done.load(std::memory_order_acquire)) {
    buffer.drain(take);
  }
  buffer.drain(take);
  producer.join();
  EXPECT_TRUE(in_order);
  EXPECT_EQ(received, accepted);
  EXPECT_EQ(received + buffer.overflow_count(), kIterations);
}

}  // namespace
}  // namespace core
