// fan-firmware: the fan board's firmware for a Linux target on SocketCAN. Its
// components (components.hpp) in hil-rig's board application, which gives it the rig's command
// line (`fan-firmware --help`), the lockstep and free-running loops, LSS, parameter
// storage, program download and the recorder.
#include "components.hpp"
#include "hilfw/Board.hpp"

int main(int argc, char** argv) {
  return hilfw::run_board<fan::Components>(
      argc, argv, {.description = "Firmware of the fan board", .rogue_target = board::FieldId::fan_duty});
}
