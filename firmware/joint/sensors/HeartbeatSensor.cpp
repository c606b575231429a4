#include "joint/sensors/HeartbeatSensor.hpp"

namespace joint {

using board::FieldId;

HeartbeatSensor::HeartbeatSensor(core::MessageBoard& board, HeartbeatInput& heartbeat)
    : Sensor(board, "heartbeat", {.writes = {FieldId::heartbeat_lost}}), heartbeat_{heartbeat} {}

void HeartbeatSensor::update() {
  const HeartbeatSample sample = heartbeat_.read();
  boardSet(FieldId::heartbeat_lost, sample.lost_now || sample.lost_since_last_read ? 1.0F : 0.0F);
}

}  // namespace joint
