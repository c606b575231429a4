#include "joint/virtual_sensors/JointTorque.hpp"

#include "joint/BoardReads.hpp"

namespace joint {

using board::FieldId;

JointTorque::JointTorque(core::MessageBoard& board)
    : VirtualSensor(board, "joint_torque",
                    {.writes = {FieldId::joint_torque},
                     .reads = {FieldId::spring_deflection, FieldId::spring_constant_nominal}}) {}

void JointTorque::update() {
  if (!written_this_cycle(board(), FieldId::spring_deflection)) {
    return;
  }
  boardSet(FieldId::joint_torque,
           spring_torque_nm(boardGet(FieldId::spring_deflection), boardGet(FieldId::spring_constant_nominal)));
}

}  // namespace joint
