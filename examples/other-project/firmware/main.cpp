// lamp-firmware: the toy lamp's firmware for a Linux target on SocketCAN, built from hil-rig's
// installed firmware package (find_package(hilfw)): its components (LampComponents.hpp) in
// hilfw's board application, which gives it the rig's command line (`lamp-firmware --help`),
// the lockstep and free-running loops, LSS, parameter storage, program download and the
// recorder.
#include "LampComponents.hpp"
#include "hilfw/Board.hpp"

int main(int argc, char** argv) {
  return hilfw::run_board<lamp::Components>(argc, argv,
                                            {.description = "Firmware of the toy lamp (a photodiode, a PWM lamp)",
                                             .rogue_target = board::FieldId::light_level,
                                             .program = "lamp-firmware"});
}
