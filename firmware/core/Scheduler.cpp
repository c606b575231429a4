#include "core/Scheduler.hpp"

#include <algorithm>
#include <array>
#include <cstddef>
#include <optional>

namespace core {
namespace {

std::string field_name(FieldId id) { return std::string(board::info(id).name); }

std::string_view to_string(board::Kind kind) {
  switch (kind) {
    case board::Kind::Sensor:
      return "sensor";
    case board::Kind::VirtualSensor:
      return "virtual sensor";
    case board::Kind::Module:
      return "module";
    case board::Kind::Actuator:
      return "actuator";
    case board::Kind::Command:
      return "command";
    case board::Kind::Parameter:
      return "parameter";
  }
  return "unknown";
}

// Which fields (by their kind in board.toml) a component of each kind may write.
bool may_write(ComponentKind component, const board::FieldInfo& field) {
  switch (component) {
    case ComponentKind::Sensor:
      return field.kind == board::Kind::Sensor;
    case ComponentKind::VirtualSensor:
      return field.kind == board::Kind::VirtualSensor;
    case ComponentKind::Module:
      return field.kind == board::Kind::Module;
    case ComponentKind::Actuator:
      return false;
    case ComponentKind::External:
      return field.access == board::Access::ReadWrite;
  }
  return false;
}

std::string_view plural(ComponentKind kind) {
  switch (kind) {
    case ComponentKind::Sensor:
      return "sensors";
    case ComponentKind::VirtualSensor:
      return "virtual sensors";
    case ComponentKind::Module:
      return "modules";
    case ComponentKind::Actuator:
      return "actuators";
    case ComponentKind::External:
      return "external writers";
  }
  return "components";
}

std::optional<FieldId> first_of(const FieldSet& set) {
  std::optional<FieldId> first;
  set.for_each([&](FieldId id) {
    if (!first) {
      first = id;
    }
  });
  return first;
}

// The rules a component's declarations must follow on their own.
StartupStatus check_declarations(const MessageBoardUser& user) {
  const Declarations& declared = user.declarations();
  if (const auto both = first_of(declared.reads & declared.reads_last_cycle)) {
    return StartupStatus::failure(StartupError::ConflictingRead,
                                  describe(user) + " declares '" + field_name(*both) +
                                      "' both as a read and as a last-cycle read; keep one");
  }
  if (user.kind() == ComponentKind::Sensor) {
    const FieldSet parameters =
        FieldSet::where([](const board::FieldInfo& field) { return field.kind == board::Kind::Parameter; });
    FieldSet all_reads = declared.reads | declared.reads_last_cycle;
    parameters.for_each([&](FieldId id) { all_reads.erase(id); });
    if (const auto read = first_of(all_reads)) {
      return StartupStatus::failure(
          StartupError::SensorReadsBoard,
          describe(user) + " declares a read of '" + field_name(*read) + "' (a " +
              std::string(to_string(board::info(*read).kind)) +
              " field); a Sensor turns hardware input into board fields and may read only parameters; "
              "make it a virtual sensor if it derives its value from other fields");
    }
  }
  if (user.kind() == ComponentKind::Actuator) {
    if (const auto write = first_of(declared.writes)) {
      return StartupStatus::failure(StartupError::ActuatorWritesBoard,
                                    describe(user) + " declares a write of '" + field_name(*write) +
                                        "'; an Actuator only reads the board and drives hardware");
    }
  }
  std::optional<FieldId> misfit;
  declared.writes.for_each([&](FieldId id) {
    if (!misfit && !may_write(user.kind(), board::info(id))) {
      misfit = id;
    }
  });
  if (misfit) {
    const board::FieldInfo& field = board::info(*misfit);
    const std::string rule = user.kind() == ComponentKind::External
                                 ? "an external writer writes only bus-writable (rw) fields"
                                 : "a component writes only fields of its own kind";
    return StartupStatus::failure(StartupError::WrongFieldKind,
                                  describe(user) + " declares a write of '" + std::string(field.name) +
                                      "', a " + std::string(to_string(field.kind)) + " field; " + rule);
  }
  return StartupStatus::success();
}

struct Edge {
  std::size_t writer;  // index into the components of one kind
  std::size_t reader;
  FieldId field;
};

// Spells out a cycle among `remaining` (every one of them has a predecessor
// among them): walk predecessors until a component repeats, then print the
// loop in data-flow order, writer -> field -> reader.
std::string describe_cycle(const std::vector<MessageBoardUser*>& components, const std::vector<Edge>& edges,
                           const std::vector<bool>& remaining) {
  std::size_t start = 0;
  while (!remaining[start]) {
    ++start;
  }
  std::vector<std::size_t> walk;  // components, each a successor of the next
  std::vector<FieldId> via;       // via[i]: field from walk[i + 1] to walk[i]
  std::vector<bool> seen(components.size(), false);
  std::size_t current = start;
  while (!seen[current]) {
    seen[current] = true;
    walk.push_back(current);
    const auto edge = std::find_if(edges.begin(), edges.end(), [&](const Edge& e) {
      return e.reader == current && remaining[e.writer];
    });
    // Every remaining component has a remaining predecessor, so edge is found.
    via.push_back(edge->field);
    current = edge->writer;
  }
  const auto loop_start = static_cast<std::size_t>(std::find(walk.begin(), walk.end(), current) - walk.begin());
  // walk[i + 1] writes via[i], which walk[i] reads; the last step closes the
  // loop at walk[loop_start].
  std::string text(components[walk[loop_start]]->name());
  for (std::size_t i = walk.size(); i-- > loop_start;) {
    text += " -> " + field_name(via[i]) + " -> " + std::string(components[walk[i]]->name());
  }
  return text;
}

// Orders one kind's components topologically; ties keep add() order.
StartupStatus order_kind(ComponentKind kind, const std::vector<MessageBoardUser*>& components,
                         const std::array<const MessageBoardUser*, board::kFieldCount>& writer_of,
                         std::vector<MessageBoardUser*>& order) {
  std::vector<Edge> edges;
  for (std::size_t reader = 0; reader < components.size(); ++reader) {
    components[reader]->declarations().reads.for_each([&](FieldId id) {
      const MessageBoardUser* writer = writer_of[field_index(id)];
      if (writer == nullptr || writer == components[reader] || writer->kind() != kind) {
        return;
      }
      const auto it = std::find(components.begin(), components.end(), writer);
      edges.push_back({static_cast<std::size_t>(it - components.begin()), reader, id});
    });
  }
  std::vector<std::size_t> pending_inputs(components.size(), 0);
  for (const Edge& edge : edges) {
    ++pending_inputs[edge.reader];
  }
  std::vector<bool> remaining(components.size(), true);
  for (std::size_t placed = 0; placed < components.size(); ++placed) {
    std::size_t next = 0;
    while (next < components.size() && !(remaining[next] && pending_inputs[next] == 0)) {
      ++next;
    }
    if (next == components.size()) {
      return StartupStatus::failure(StartupError::UpdateOrderCycle,
                                    "update-order cycle among " + std::string(plural(kind)) + ": " +
                                        describe_cycle(components, edges, remaining) +
                                        " (each writes a field the next reads this cycle); declare one of "
                                        "these reads as reads_last_cycle to break it");
    }
    remaining[next] = false;
    order.push_back(components[next]);
    for (const Edge& edge : edges) {
      if (edge.writer == next) {
        --pending_inputs[edge.reader];
      }
    }
  }
  return StartupStatus::success();
}

std::string join_fields(const FieldSet& fields, const FieldSet& last_cycle,
                        const std::array<const MessageBoardUser*, board::kFieldCount>* writer_of) {
  std::string text;
  (fields | last_cycle).for_each([&](FieldId id) {
    if (!text.empty()) {
      text += ", ";
    }
    text += field_name(id);
    if (last_cycle.contains(id)) {
      text += " (last cycle)";
    }
    if (writer_of != nullptr && (*writer_of)[field_index(id)] == nullptr) {
      text += " (no writer)";
    }
  });
  return text.empty() ? "-" : text;
}

}  // namespace

bool Scheduler::add(MessageBoardUser& component) {
  if (started_) {
    return false;
  }
  added_.push_back(&component);
  return true;
}

StartupStatus Scheduler::start() {
  if (started_) {
    return StartupStatus::failure(StartupError::AlreadyStarted, "the scheduler was already started");
  }
  for (std::size_t i = 0; i < added_.size(); ++i) {
    for (std::size_t j = 0; j < i; ++j) {
      if (added_[j]->name() == added_[i]->name()) {
        const std::string what =
            added_[j] == added_[i] ? " was added twice" : " shares its name with " + describe(*added_[j]);
        return StartupStatus::failure(StartupError::DuplicateName, describe(*added_[i]) + what);
      }
    }
  }
  for (const MessageBoardUser* component : added_) {
    if (StartupStatus status = check_declarations(*component); !status) {
      return status;
    }
  }

  // Owners: one per field, among the added components and any owner the
  // board already has. Checked in full before the board is touched.
  std::array<const MessageBoardUser*, board::kFieldCount> writer_of{};
  for (std::size_t i = 0; i < board::kFieldCount; ++i) {
    writer_of[i] = board_.owner(static_cast<FieldId>(i));
  }
  for (const MessageBoardUser* component : added_) {
    std::optional<FieldId> taken;
    component->declarations().writes.for_each([&](FieldId id) {
      const MessageBoardUser*& writer = writer_of[field_index(id)];
      if (writer != nullptr && writer != component) {
        taken = taken ? taken : id;
        return;
      }
      writer = component;
    });
    if (taken) {
      return StartupStatus::failure(StartupError::DuplicateWriter,
                                    "field '" + field_name(*taken) + "' is declared as written by both " +
                                        describe(*writer_of[field_index(*taken)]) + " and " + describe(*component) +
                                        "; every field has exactly one writer");
    }
  }

  // Reads of fields written by a later kind must be last-cycle reads.
  for (const MessageBoardUser* reader : added_) {
    std::optional<FieldId> late;
    reader->declarations().reads.for_each([&](FieldId id) {
      const MessageBoardUser* writer = writer_of[field_index(id)];
      if (!late && writer != nullptr && writer->kind() != ComponentKind::External && writer->kind() > reader->kind()) {
        late = id;
      }
    });
    if (late) {
      const MessageBoardUser& writer = *writer_of[field_index(*late)];
      return StartupStatus::failure(
          StartupError::ReadOfLaterKind,
          describe(*reader) + " reads '" + field_name(*late) + "' as this cycle's value, but it is written by " +
              describe(writer) + ", and " + std::string(plural(writer.kind())) + " run after " +
              std::string(plural(reader->kind())) + "; declare it in reads_last_cycle to use last cycle's value");
    }
  }

  std::vector<MessageBoardUser*> order;
  std::vector<MessageBoardUser*> external;
  for (const ComponentKind kind :
       {ComponentKind::Sensor, ComponentKind::VirtualSensor, ComponentKind::Module, ComponentKind::Actuator}) {
    std::vector<MessageBoardUser*> of_kind;
    std::copy_if(added_.begin(), added_.end(), std::back_inserter(of_kind),
                 [&](const MessageBoardUser* component) { return component->kind() == kind; });
    if (StartupStatus status = order_kind(kind, of_kind, writer_of, order); !status) {
      return status;
    }
  }
  std::copy_if(added_.begin(), added_.end(), std::back_inserter(external),
               [](const MessageBoardUser* component) { return component->kind() == ComponentKind::External; });

  for (const MessageBoardUser* component : added_) {
    // Cannot fail: every declared write was checked against the board's owners above.
    if (StartupStatus status = board_.claim_writes(*component); !status) {
      return status;
    }
  }
  order_ = std::move(order);
  external_ = std::move(external);
  started_ = true;
  return StartupStatus::success();
}

std::string Scheduler::schedule_text() const {
  std::array<const MessageBoardUser*, board::kFieldCount> writer_of{};
  for (std::size_t i = 0; i < board::kFieldCount; ++i) {
    writer_of[i] = board_.owner(static_cast<FieldId>(i));
  }
  std::string text = "Update order (" + std::to_string(order_.size()) + " components per cycle):\n";
  std::size_t position = 1;
  for (const MessageBoardUser* component : order_) {
    const Declarations& declared = component->declarations();
    text += "  " + std::to_string(position++) + ". " + describe(*component) + "\n";
    text += "       writes: " + join_fields(declared.writes, FieldSet{}, nullptr) + "\n";
    text += "       reads:  " + join_fields(declared.reads, declared.reads_last_cycle, &writer_of) + "\n";
  }
  text += "Not scheduled (write between cycles): " + std::to_string(external_.size()) + "\n";
  for (const MessageBoardUser* component : external_) {
    text += "  - " + describe(*component) + "\n";
    text += "       writes: " + join_fields(component->declarations().writes, FieldSet{}, nullptr) + "\n";
  }
  return text;
}

void Scheduler::print_schedule(TextSink sink, void* context) const {
  const std::string text = schedule_text();
  sink(context, text);
}

}  // namespace core
