// What the engine needs from the rest of the firmware. The platform implements these and
// wires them to the message board, the HIL driver registers and persistent storage in main().
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "board/fields.hpp"

namespace co {

enum class WriteResult : std::uint8_t {
  Accepted,  // the board took the value
  Refused,   // the board refused it (e.g. the node does not own the field); value unchanged
};

// Board access on behalf of the bus. The engine range-checks against board::kFields before
// calling write(), so implementations only decide ownership.
class FieldAccess {
 public:
  virtual ~FieldAccess() = default;
  virtual float read(board::FieldId id) = 0;
  virtual WriteResult write(board::FieldId id, float value) = 0;

 protected:
  FieldAccess() = default;
  FieldAccess(const FieldAccess&) = default;
  FieldAccess& operator=(const FieldAccess&) = default;
};

// Raw hardware-in-the-loop I/O. Inputs land in the driver's intermediate registers (never the
// board: Sensors drain them in update()); outputs are what the Actuators last commanded.
// Values are already range-checked against board::kHilInputs.
class HilIo {
 public:
  virtual ~HilIo() = default;
  virtual void write_input(board::HilInputId id, std::int32_t raw) = 0;
  virtual std::int32_t read_output(board::HilOutputId id) = 0;

 protected:
  HilIo() = default;
  HilIo(const HilIo&) = default;
  HilIo& operator=(const HilIo&) = default;
};

// The heartbeat consumer's (0x1016) news for the application. Like HilIo inputs it goes to an
// intermediate register (never the board): a component drains it in its update().
class HeartbeatListener {
 public:
  virtual ~HeartbeatListener() = default;
  // Called when something changed. `lost_entries`: entries whose heartbeat timed out and has not
  // come back; `event`: this call reports a new heartbeat event (an entry just timed out).
  virtual void heartbeat_status(std::uint8_t lost_entries, bool event) = 0;

 protected:
  HeartbeatListener() = default;
  HeartbeatListener(const HeartbeatListener&) = default;
  HeartbeatListener& operator=(const HeartbeatListener&) = default;
};

// The receive filter in front of the node: a CAN controller's acceptance filter, SocketCAN's
// CAN_RAW_FILTER. A frame on any COB-ID outside the node's accepted set (Node::accepted_ids),
// and every remote or 29-bit frame, the node would only count as ignored, so the filter may
// drop it before it wakes the firmware.
class AcceptanceListener {
 public:
  virtual ~AcceptanceListener() = default;
  // Called from inside Node::start() and Node::process() when the set changed, before the node
  // sends the frame after which a master may use a new id (the boot-up, the SDO answer): apply
  // it before returning. `cob_ids`: 11-bit identifiers, ascending, each once.
  virtual void accepted_ids_changed(std::span<const std::uint32_t> cob_ids) = 0;

 protected:
  AcceptanceListener() = default;
  AcceptanceListener(const AcceptanceListener&) = default;
  AcceptanceListener& operator=(const AcceptanceListener&) = default;
};

// Persistent bytes for "store parameters" (0x1010). The engine frames the image with a magic,
// version and CRC, so implementations just keep bytes.
class ParameterStorage {
 public:
  virtual ~ParameterStorage() = default;
  // Replaces the stored image. true: durable (old image replaced); false: old image kept.
  virtual bool save(std::span<const std::byte> image) = 0;
  // Copies the stored image into `buffer`. Returns its size; 0 when nothing is stored, it
  // cannot be read, or it is larger than `buffer`.
  virtual std::size_t load(std::span<std::byte> buffer) = 0;

 protected:
  ParameterStorage() = default;
  ParameterStorage(const ParameterStorage&) = default;
  ParameterStorage& operator=(const ParameterStorage&) = default;
};

}  // namespace co
