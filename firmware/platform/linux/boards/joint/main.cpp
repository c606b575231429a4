// joint-firmware: the demo series-elastic joint's firmware for a Linux target on SocketCAN
// (hilfw::run_board, hilfw/Board.hpp): its components on its driver registers.
#include "hilfw/Board.hpp"
#include "joint/DemoJoint.hpp"
#include "joint/drivers/HilRegisters.hpp"

namespace {

class Components {
 public:
  Components(core::MessageBoard& board, joint::HilRegisters& registers, float dt_s)
      : joint_{board, registers.drivers(), dt_s} {}
  bool add_to(core::Scheduler& scheduler) { return joint_.add_to(scheduler); }

 private:
  joint::DemoJoint joint_;
};

}  // namespace

int main(int argc, char** argv) {
  return hilfw::run_board<Components, joint::HilRegisters>(
      argc, argv,
      {.description = "Firmware of the demo series-elastic joint",
       .rogue_target = board::FieldId::motor_duty_command,
       .rogue_value = 0.875F,  // a duty the joint's owner never commands at rest
       .program = "joint-firmware"});
}
