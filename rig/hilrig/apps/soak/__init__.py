"""The soak: a million lockstep cycles against the real firmware on a real SocketCAN bus, with
seeded faults now and then; no cycle may be lost and the firmware's memory must stay flat
(`hilrig soak`, `make soak`). `run` is the entry and says the whole of it in its docstring; the
parts, by concern: what is sent and expected, from the EDS (`layout`), the seeded fault schedule
(`fault_plan`), the firmware process's memory (`memory`), the judge of every cycle (`checker`),
the run on the engine's lockstep driver with the faults between its cycles (`soak`), and the
report (`report`).
"""
