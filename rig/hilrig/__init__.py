"""The rig of the hardware-in-the-loop CAN test rig: physics of the demo joint and its tools."""

from hilrig import mf4_deferred

mf4_deferred.install()
