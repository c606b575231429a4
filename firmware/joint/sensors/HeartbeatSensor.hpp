// The node's heartbeat consumer -> heartbeat_lost (1 while a watched heartbeat is lost, or in the
// cycle after a loss that already ended; else 0), written every cycle. The FaultManager latches
// it; the node itself never writes the board.
#pragma once

#include "core/MessageBoardUser.hpp"
#include "joint/drivers/HeartbeatInput.hpp"

namespace joint {

class HeartbeatSensor final : public core::Sensor {
 public:
  // `heartbeat` must outlive the sensor.
  HeartbeatSensor(core::MessageBoard& board, HeartbeatInput& heartbeat);

  void update() override;

 private:
  HeartbeatInput& heartbeat_;
};

}  // namespace joint
