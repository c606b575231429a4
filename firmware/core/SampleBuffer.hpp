// An intermediate register for inputs sampled faster than the control cycle:
// the receive path pushes every sample, the Sensor drains them all in update()
// and filters them (the seed's driving example for its interrupt policy).
//
// Single producer, single consumer, lock-free ring of N slots. A push into a
// full buffer drops that sample and counts an overflow: the producer never
// touches the consumer's index, so it never waits.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <span>
#include <type_traits>

namespace core {

template <typename T, std::size_t N>
class SampleBuffer {
  static_assert(std::is_trivially_copyable_v<T>, "samples are copied as raw bytes");
  static_assert(N > 0 && (N & (N - 1)) == 0, "N must be a power of two (indices wrap by masking)");
  static_assert(N <= (std::size_t{1} << 31), "indices are 32-bit counters");

 public:
  SampleBuffer() = default;
  SampleBuffer(const SampleBuffer&) = delete;
  SampleBuffer& operator=(const SampleBuffer&) = delete;

  static constexpr std::size_t capacity() { return N; }

  // Producer side. Returns false, and counts an overflow, if the buffer is full.
  bool push(const T& sample) {
    const std::uint32_t head = head_.load(std::memory_order_relaxed);
    const std::uint32_t tail = tail_.load(std::memory_order_acquire);
    if (head - tail == N) {
      overflows_.store(overflows_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
      return false;
    }
    slots_[head & kMask] = sample;
    head_.store(head + 1, std::memory_order_release);
    return true;
  }

  // Consumer side: calls sink(const T&) for every buffered sample, oldest
  // first, and returns how many it drained.
  template <typename Sink>
  std::size_t drain(Sink&& sink) {
    const std::uint32_t tail = tail_.load(std::memory_order_relaxed);
    const std::uint32_t head = head_.load(std::memory_order_acquire);
    for (std::uint32_t i = tail; i != head; ++i) {
      sink(slots_[i & kMask]);
    }
    tail_.store(head, std::memory_order_release);
    return head - tail;
  }

  // Consumer side: moves up to out.size() samples, oldest first, into out and
  // returns how many. Samples that do not fit stay for the next call.
  std::size_t drain_into(std::span<T> out) {
    const std::uint32_t tail = tail_.load(std::memory_order_relaxed);
    const std::uint32_t head = head_.load(std::memory_order_acquire);
    const std::uint32_t available = head - tail;
    const std::uint32_t count =
        out.size() < available ? static_cast<std::uint32_t>(out.size()) : available;
    for (std::uint32_t i = 0; i < count; ++i) {
      out[i] = slots_[(tail + i) & kMask];
    }
    tail_.store(tail + count, std::memory_order_release);
    return count;
  }

  // Samples waiting; exact on the consumer side, a lower bound elsewhere.
  std::size_t size() const {
    const std::uint32_t tail = tail_.load(std::memory_order_acquire);  // first: head never falls behind it
    return head_.load(std::memory_order_acquire) - tail;
  }

  // Samples dropped because the buffer was full, since construction.
  std::uint32_t overflow_count() const { return overflows_.load(std::memory_order_relaxed); }

 private:
  static constexpr std::uint32_t kMask = static_cast<std::uint32_t>(N - 1);

  std::array<T, N> slots_{};
  std::atomic<std::uint32_t> head_{0};  // written by the producer only
  std::atomic<std::uint32_t> tail_{0};  // written by the consumer only
  std::atomic<std::uint32_t> overflows_{0};
};

}  // namespace core
