"""The apps: programs on top of the engine and the session, never beside them. The demo and the
robot demo (`demo`, `robot_demo`), the soak (`soak/`), the bus load model (`busload`), the field
recorder's capture (`capture`), bus logs turned into traces (`log_trace`) and the bus scan
(`scan`). They may import every layer but the CLI, which is built on them.
"""
