"""The bench (`make bench`, `make bench-baseline`, through tools/bench.py): every figure a ratio
of two things measured side by side in one run, on top of the engine and the session like the
demo and the soak. `main` is the command line and says in its docstring what is measured and
against what; the parts, by concern: what every step shares (`common`: the checkout, the
progress line, a measurement's time budget, probes that fail without stopping the run), the
native step (`native`: fw_board_bench, callgrind counts, the rig probe; `size`, `cycles`, `virt`:
the Cortex-M and bare-metal images), the engine against a baseline commit's (`baseline`), the bus
step (`bus` schedules, `bus_measure` measures on a private bus), the report (`report`), the Rig's
own cycle natively (`probe`, run by tools/rig_probe.py), and what a scenario spends outside its
cycles (`scenario_costs`, not in `make bench`).
"""
