"""The lamp's first scenario: the firmware on a private vcan, the rig with the lamp plant."""

from __future__ import annotations


def test_the_light_follows_its_setpoint(make_scenario) -> None:
    s = make_scenario(seed=1)  # firmware + rig + plant on a private vcan, traced
    s.rig.set("light_setpoint", 0.6)  # RPDO2, sent as it changes
    s.rig.run(seconds=0.4)  # simulation time
    s.expect.settles_within("light_level", target=0.6, tolerance=0.02, by_s=0.3)
    _, pwm = s.rig.history("lamp_pwm")
    assert pwm[-1] == 6000  # the node's PWM as the lamp got it
