"""The soak: a million lockstep cycles against the real firmware on a real SocketCAN bus, with
seeded faults now and then; no cycle may be lost and the firmware's memory must stay flat
(`hilrig soak`, `make soak`). `run` has the whole of it; see its docstring.
"""
