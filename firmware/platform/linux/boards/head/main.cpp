// head-firmware: the robot head module's firmware for a Linux target on SocketCAN
// (hilfw::run_board, hilfw/Board.hpp): its components on its driver registers.
#include "head/HeadModule.hpp"
#include "head/drivers/HeadRegisters.hpp"
#include "hilfw/Board.hpp"

namespace {

class Components {
 public:
  // The head's components keep no time constant: dt_s is not used.
  Components(core::MessageBoard& board, head::HeadRegisters& registers, float /*dt_s*/)
      : head_{board, registers.drivers()} {}
  bool add_to(core::Scheduler& scheduler) { return head_.add_to(scheduler); }

 private:
  head::HeadModule head_;
};

}  // namespace

int main(int argc, char** argv) {
  return hilfw::run_board<Components, head::HeadRegisters>(
      argc, argv,
      {.description = "Firmware of the robot head module (IMU, RGB LED, current-limited power rail, battery)",
       .rogue_target = board::FieldId::led_red_duty,
       .rogue_value = 0.875F,  // a duty the LED mixer never writes with the LED off
       .program = "head-firmware"});
}
