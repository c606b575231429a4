"""The Rerun blueprint of the robot head module (protocol/boards/head.toml), the second board:
its power (rail current against its limit, battery voltage against its low limit), its LED
(commanded, driven, true), its attitude from the IMU against the plant's, the rail and fault
state, and the event log (EMCY of a trip or a low battery).

    .venv/bin/rerun out/scenarios/<test>/trace.rrd      # a head scenario's trace carries it
    blueprint("head", RigTable.load(resources.HEAD_TABLE))

Built like the joint's (dashboards/joint.py): paths from `hilrig.observe.paths`, every field name
checked against the table given, the truth's names the head plant's (`hilrig.plants.head`).
"""

from __future__ import annotations

import rerun.blueprint as rrb

from dashboards.joint import Paths, blueprint_of, events, plot
from hilrig.observe.paths import EntryTable, plant_truth_path

LED_COLOURS = ("red", "green", "blue")


def head(table: EntryTable) -> rrb.Blueprint:
    """Is the head doing what it is told, and is its power healthy? One unit per plot."""
    p = Paths(table)
    leds = [f"led_{colour}" for colour in LED_COLOURS]
    return blueprint_of(rrb.Vertical(
        rrb.Grid(
            plot("rail current [A]: measured, limit, true",
                 [*p("rail_current", "rail_current_limit"), plant_truth_path("rail_current_a")]),
            plot("battery voltage [V]: measured, low limit, true",
                 [*p("battery_voltage", "battery_low_voltage"), plant_truth_path("battery_voltage_v")]),
            plot("LED [1]: commanded, driven by the firmware, true duty",
                 [*p(*leds, *(f"{led}_duty" for led in leds)),
                  *(plant_truth_path(f"{led}_duty") for led in leds)]),
            plot("head attitude [rad]: firmware estimate vs true",
                 [*p("head_pitch", "head_roll"), *(plant_truth_path(q) for q in ("pitch_rad", "roll_rad"))]),
            plot("IMU rates [rad/s]: gyro y, z vs true pitch and yaw rate",
                 [*p("gyro_y", "gyro_z"), *map(plant_truth_path, ("pitch_rate_rad_s", "yaw_rate_rad_s"))]),
            plot("rail and faults [1]: rail_enable, rail_on, fault_flags, fault_clear",
                 p("rail_enable", "rail_on", "fault_flags", "fault_clear")),
            plot("state of charge [1], true", [plant_truth_path("battery_state_of_charge")]),
        ),
        events(),
        row_shares=[4, 1],
    ))
