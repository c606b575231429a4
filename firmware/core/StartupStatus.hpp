// The outcome of a start-up step (ownership registration, scheduling).
// The core builds without exceptions, so errors are returned: an enum a
// program can branch on plus a sentence a person can act on. The message is
// a std::string because it only exists at start-up, never in the cycle.
#pragma once

#include <cstdint>
#include <string>
#include <utility>

namespace core {

enum class StartupError : std::uint8_t {
  None,
  // Two components declare a write of the same field.
  DuplicateWriter,
  // Two components share a name (or one component was added twice).
  DuplicateName,
  // A field is declared both as a read and as a last-cycle read.
  ConflictingRead,
  // A component declares a write of a field whose kind in board.toml does not
  // match the component's kind (a Module writing a Sensor field, say).
  WrongFieldKind,
  // A Sensor declares a read of a field other than a Parameter.
  SensorReadsBoard,
  // An Actuator declares a write.
  ActuatorWritesBoard,
  // A component reads, as this cycle's value, a field written by a kind that
  // runs after it.
  ReadOfLaterKind,
  // The declared reads and writes within one kind form a cycle.
  UpdateOrderCycle,
  // Scheduler::start() was called a second time.
  AlreadyStarted,
};

class [[nodiscard]] StartupStatus {
 public:
  static StartupStatus success() { return StartupStatus{}; }
  static StartupStatus failure(StartupError error, std::string message) {
    return StartupStatus{error, std::move(message)};
  }

  bool ok() const { return error_ == StartupError::None; }
  explicit operator bool() const { return ok(); }
  StartupError error() const { return error_; }
  // Empty on success.
  const std::string& message() const { return message_; }

 private:
  StartupStatus() = default;
  StartupStatus(StartupError error, std::string message) : error_{error}, message_{std::move(message)} {}

  StartupError error_ = StartupError::None;
  std::string message_;
};

}  // namespace core
