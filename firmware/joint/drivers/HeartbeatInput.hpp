// The CANopen node's heartbeat consumer (0x1016) as the joint sees it: whether a heartbeat it
// watches (the bus master's) is lost now, and whether one was lost since the previous read, so
// a loss that ended between two cycles is not missed.
#pragma once

namespace joint {

struct HeartbeatSample {
  bool lost_now;              // a watched heartbeat timed out and has not come back
  bool lost_since_last_read;  // a heartbeat event happened since the previous read()
};

class HeartbeatInput {
 public:
  virtual ~HeartbeatInput() = default;
  // Consumes the event: a second read() without a new event reports lost_since_last_read false.
  virtual HeartbeatSample read() = 0;

 protected:
  HeartbeatInput() = default;
  HeartbeatInput(const HeartbeatInput&) = default;
  HeartbeatInput& operator=(const HeartbeatInput&) = default;
};

}  // namespace joint
