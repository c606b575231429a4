// The component base of the seed (MessageBoardUser) and the component kinds.
//
// A component states in its constructor which fields it writes and which it
// reads; the Scheduler derives ownership and the update order from that:
//
//   class VelocityController final : public core::Module {
//    public:
//     explicit VelocityController(core::MessageBoard& board)
//         : Module(board, "velocity_controller",
//                  {.writes = {FieldId::velocity_controller_output},
//                   .reads = {FieldId::motor_velocity, FieldId::velocity_setpoint},
//                   .reads_last_cycle = {FieldId::motor_duty_command}}) {}
//     void update() override;
//   };
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "board/fields.hpp"
#include "core/FieldSet.hpp"
#include "core/MessageBoard.hpp"

namespace core {

// Scheduled kinds run in this order every cycle. External writers (the
// CANopen node) are not scheduled: they write between cycles.
enum class ComponentKind : std::uint8_t { Sensor, VirtualSensor, Module, Actuator, External };

std::string_view to_string(ComponentKind kind);

struct Declarations {
  FieldSet writes{};            // fields this component owns
  FieldSet reads{};             // read as this cycle's value: the writer runs first
  FieldSet reads_last_cycle{};  // read as last cycle's value: adds no ordering edge
};

class MessageBoardUser {
 public:
  MessageBoardUser(const MessageBoardUser&) = delete;
  MessageBoardUser& operator=(const MessageBoardUser&) = delete;
  virtual ~MessageBoardUser() = default;

  // Called once per control cycle, in the Scheduler's order.
  virtual void update() = 0;

  std::string_view name() const { return name_; }
  ComponentKind kind() const { return kind_; }
  const Declarations& declarations() const { return declarations_; }

 protected:
  // `name` must outlive the component (a string literal): it is kept as a view.
  // The board must outlive the component too.
  MessageBoardUser(MessageBoard& board, ComponentKind kind, std::string_view name, const Declarations& declarations)
      : board_{board}, kind_{kind}, name_{name}, declarations_{declarations} {}

  // The seed's wrappers: the component passes itself as the writer.
  SetResult boardSet(FieldId id, float value) { return board_.set(*this, id, value); }
  float boardGet(FieldId id) const { return board_.get(id); }
  bool boardHas(FieldId id) const { return board_.has(id); }
  bool boardIsStale(FieldId id, std::uint32_t max_age_cycles) const { return board_.is_stale(id, max_age_cycles); }
  const MessageBoard& board() const { return board_; }

 private:
  MessageBoard& board_;
  ComponentKind kind_;
  std::string_view name_;
  Declarations declarations_;
};

// Hardware input -> board. Reads its driver (usually an intermediate register
// the receive path fills); reads no board field except Parameters.
class Sensor : public MessageBoardUser {
 protected:
  Sensor(MessageBoard& board, std::string_view name, const Declarations& declarations)
      : MessageBoardUser(board, ComponentKind::Sensor, name, declarations) {}
};

// Board -> board derived measurements (velocity from position, torque from deflection).
class VirtualSensor : public MessageBoardUser {
 protected:
  VirtualSensor(MessageBoard& board, std::string_view name, const Declarations& declarations)
      : MessageBoardUser(board, ComponentKind::VirtualSensor, name, declarations) {}
};

// Behaviour: controllers, estimators, safety.
class Module : public MessageBoardUser {
 protected:
  Module(MessageBoard& board, std::string_view name, const Declarations& declarations)
      : MessageBoardUser(board, ComponentKind::Module, name, declarations) {}
};

// Board -> hardware output. Writes no board field.
class Actuator : public MessageBoardUser {
 protected:
  Actuator(MessageBoard& board, std::string_view name, const Declarations& declarations)
      : MessageBoardUser(board, ComponentKind::Actuator, name, declarations) {}
};

// A writer outside the control cycle, such as the CANopen node: it owns the
// bus-writable fields (declare `.writes = kBusWritableFields`) and writes them
// from its own entry points between cycles. The Scheduler registers its
// ownership but never calls update(), which therefore does nothing by default.
class ExternalWriter : public MessageBoardUser {
 public:
  void update() override {}

 protected:
  ExternalWriter(MessageBoard& board, std::string_view name, const Declarations& declarations)
      : MessageBoardUser(board, ComponentKind::External, name, declarations) {}
};

// "module 'velocity_controller'": how errors name a component.
std::string describe(const MessageBoardUser& user);

}  // namespace core
