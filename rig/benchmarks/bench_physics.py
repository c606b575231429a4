"""Cost of the physics per control cycle (1 ms of simulation), as the lockstep driver spends it.

Run natively:      .venv/bin/python rig/benchmarks/bench_physics.py
Run in the VM:     tools/with-vcan -- .venv/bin/python rig/benchmarks/bench_physics.py
(the micro-VM emulates the CPU in software, where Python's float code is slowest).
"""

from __future__ import annotations

import argparse
import struct
import time
from collections.abc import Callable

from hilrig.plants import JointParams, JointPlant, SensorModel


def per_call_us(action: Callable[[], object], calls: int) -> float:
    start = time.perf_counter()
    for _ in range(calls):
        action()
    return (time.perf_counter() - start) / calls * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=2000)
    cycles = parser.parse_args().cycles
    params = JointParams()
    plant = JointPlant(params)
    sensors = SensorModel(params, 1)
    pack = struct.Struct("<HHHh").pack

    def lockstep_cycle() -> None:
        sensors.read(plant.state)
        plant.step(0.001, 0.3)

    results = {
        "plant.step(0.001, 0.3)": per_call_us(lambda: plant.step(0.001, 0.3), cycles),
        "plant.state": per_call_us(lambda: plant.state, cycles),
        "sensors.read(plant.state)": per_call_us(lambda: sensors.read(plant.state), cycles),
        "cycle: read(state) + step": per_call_us(lockstep_cycle, cycles),
        "struct.pack (reference)": per_call_us(lambda: pack(1, 2, 3, 4), cycles),
    }
    for name, us in results.items():
        print(f"{name:28s} {us:9.2f} us")


if __name__ == "__main__":
    main()
