// The software half of a CAN controller driver on a microcontroller: co::CanPort over two
// single-producer single-consumer rings shared with the controller's interrupts. The receive
// interrupt copies each frame out of the controller's FIFO with push_received(); the transmit
// interrupt (a mailbox empty) takes the next frame with pop_to_transmit(). The main loop only
// calls send() and receive(), so the engine never runs inside an interrupt and never waits.
// What a real port adds on top (register access, bit timing, filters):
// docs/microcontroller.md.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>

#include "canopen/CanPort.hpp"

namespace cortexm {

// One producer, one consumer, either side possibly an interrupt: each index is written by one
// side only, and the frame is written before the index that publishes it.
template <std::size_t Capacity>
class FrameRing {
  static_assert(Capacity >= 2 && (Capacity & (Capacity - 1)) == 0, "a power of two");

 public:
  bool push(const co::CanFrame& frame) {
    const std::uint32_t head = head_.load(std::memory_order_relaxed);
    if (head - tail_.load(std::memory_order_acquire) == Capacity) return false;
    frames_[head % Capacity] = frame;
    head_.store(head + 1, std::memory_order_release);
    return true;
  }
  bool pop(co::CanFrame& frame) {
    const std::uint32_t tail = tail_.load(std::memory_order_relaxed);
    if (tail == head_.load(std::memory_order_acquire)) return false;
    frame = frames_[tail % Capacity];
    tail_.store(tail + 1, std::memory_order_release);
    return true;
  }
  // Consumer side: a frame waits (a main loop asks before it sleeps, with interrupts masked).
  bool pending() const { return tail_.load(std::memory_order_relaxed) != head_.load(std::memory_order_acquire); }

 private:
  std::array<co::CanFrame, Capacity> frames_{};
  std::atomic<std::uint32_t> head_{0};
  std::atomic<std::uint32_t> tail_{0};
};

template <std::size_t RxCapacity, std::size_t TxCapacity>
class InterruptCanPort final : public co::CanPort {
 public:
  // Main loop side.
  co::SendResult send(const co::CanFrame& frame) override {
    return tx_.push(frame) ? co::SendResult::Sent : co::SendResult::QueueFull;
  }
  co::ReceiveResult receive(co::CanFrame& frame) override {
    return rx_.pop(frame) ? co::ReceiveResult::Received : co::ReceiveResult::Empty;
  }

  // Interrupt side. A frame the ring cannot take is counted: the controller's overrun.
  void push_received(const co::CanFrame& frame) {
    if (!rx_.push(frame)) receive_overruns_.fetch_add(1, std::memory_order_relaxed);
  }
  bool pop_to_transmit(co::CanFrame& frame) { return tx_.pop(frame); }
  bool received_pending() const { return rx_.pending(); }
  std::uint32_t receive_overruns() const { return receive_overruns_.load(std::memory_order_relaxed); }

 private:
  FrameRing<RxCapacity> rx_;
  FrameRing<TxCapacity> tx_;
  std::atomic<std::uint32_t> receive_overruns_{0};
};

}  // namespace cortexm
