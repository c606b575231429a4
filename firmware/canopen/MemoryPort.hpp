// In-memory CAN port: tests inject received frames and inspect what the engine sent.
#pragma once

#include <cstddef>

#include "CanPort.hpp"

namespace co {

// Fixed-capacity FIFO of frames; no heap.
template <std::size_t Capacity>
class FrameQueue {
 public:
  bool push(const CanFrame& frame) {
    if (size_ == Capacity) return false;
    frames_[(head_ + size_) % Capacity] = frame;
    ++size_;
    return true;
  }
  bool pop(CanFrame& frame) {
    if (size_ == 0) return false;
    frame = frames_[head_];
    head_ = (head_ + 1) % Capacity;
    --size_;
    return true;
  }
  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  void clear() { head_ = size_ = 0; }

 private:
  std::array<CanFrame, Capacity> frames_{};
  std::size_t head_ = 0;
  std::size_t size_ = 0;
};

class MemoryPort final : public CanPort {
 public:
  static constexpr std::size_t kCapacity = 256;

  MemoryPort() = default;
  MemoryPort(const MemoryPort&) = delete;
  MemoryPort& operator=(const MemoryPort&) = delete;

  // Sent -> appended to sent(); QueueFull when the sent queue is full or fail_sends is set.
  SendResult send(const CanFrame& frame) override {
    if (fail_sends_) return SendResult::QueueFull;
    return sent_.push(frame) ? SendResult::Sent : SendResult::QueueFull;
  }
  // Hands out injected frames in order; Empty when none are left.
  ReceiveResult receive(CanFrame& frame) override {
    return received_.pop(frame) ? ReceiveResult::Received : ReceiveResult::Empty;
  }

  // Test side.
  bool inject(const CanFrame& frame) { return received_.push(frame); }
  bool pop_sent(CanFrame& frame) { return sent_.pop(frame); }
  std::size_t sent_count() const { return sent_.size(); }
  void clear_sent() { sent_.clear(); }
  void set_fail_sends(bool fail) { fail_sends_ = fail; }

 private:
  FrameQueue<kCapacity> sent_;
  FrameQueue<kCapacity> received_;
  bool fail_sends_ = false;
};

}  // namespace co
