// An intermediate register for the seed's interrupt policy: the receive path
// (an interrupt, or the Linux event loop's frame handler) writes the newest
// raw value here, never the board; the Sensor reads it in update().
//
// Lock-free: a sequence lock over atomics. The writer never waits; the reader
// retries only while a write is in progress. One producer and one consumer.
#pragma once

#include <atomic>
#include <cstdint>
#include <type_traits>

namespace core {

template <typename T>
class LatestValueRegister {
  static_assert(std::is_trivially_copyable_v<T>, "register values are copied as raw bytes");
  static_assert(std::atomic<T>::is_always_lock_free, "an interrupt must never wait on a lock");

 public:
  struct Reading {
    T value;                             // the newest value (T{} before the first write)
    bool fresh;                          // written since the previous read()
    std::uint32_t writes_since_last_read;  // > 1: values were overwritten unread
  };

  LatestValueRegister() = default;
  LatestValueRegister(const LatestValueRegister&) = delete;
  LatestValueRegister& operator=(const LatestValueRegister&) = delete;

  // Producer side. Wait-free.
  void write(T value) {
    // Sequentially consistent throughout: a reader that sees the new value
    // then also sees the odd sequence, without stand-alone fences (which
    // ThreadSanitizer cannot check).
    const std::uint32_t sequence = sequence_.load(std::memory_order_relaxed);
    sequence_.store(sequence + 1);  // odd: write in progress
    value_.store(value);
    sequence_.store(sequence + 2);
  }

  // Consumer side: the newest value, and whether it is new since the last read().
  Reading read() {
    const Snapshot snapshot = load();
    const std::uint32_t writes = snapshot.write_count - read_write_count_;
    read_write_count_ = snapshot.write_count;
    return Reading{snapshot.value, writes != 0, writes};
  }

  // Consumer side: the newest value without consuming its freshness.
  T peek() const { return load().value; }

  // Writes since construction (wraps at 2^31).
  std::uint32_t write_count() const { return sequence_.load(std::memory_order_acquire) / 2; }

 private:
  struct Snapshot {
    T value;
    std::uint32_t write_count;
  };

  Snapshot load() const {
    for (;;) {
      const std::uint32_t before = sequence_.load();
      if ((before & 1U) != 0) {
        continue;  // a write is in progress
      }
      const T value = value_.load();
      if (sequence_.load() == before) {
        return Snapshot{value, before / 2};
      }
    }
  }

  std::atomic<T> value_{T{}};
  std::atomic<std::uint32_t> sequence_{0};  // twice the write count, odd while writing
  std::uint32_t read_write_count_ = 0;      // consumer-only
};

}  // namespace core
