"""The fan board's scenarios: its firmware on a private vcan, the rig with its plant, in
lockstep. Run: `hilrig bus -- pytest` (a trace and a bus log of each scenario go to out/)."""


def test_the_fan_holds_its_target_speed(make_scenario) -> None:
    s = make_scenario(seed=1)
    s.rig.set("speed_target_rpm", 1500.0)  # RPDO2, sent as it changes
    s.rig.run(seconds=0.6)  # simulation time
    s.expect.settles_within("fan_speed_rpm", target=1500.0, tolerance=0.02, by_s=0.4)


def test_hot_air_runs_the_fan_at_full_speed(make_scenario) -> None:
    s = make_scenario(seed=2, params={"heat_c": 60.0})  # a still fan lets the air reach 85 degC
    s.rig.set("speed_target_rpm", 300.0)
    s.rig.run(seconds=0.1)
    assert s.rig.history("fan_pwm")[1][-1] == 10_000  # above 70 degC: full speed, whatever the target
