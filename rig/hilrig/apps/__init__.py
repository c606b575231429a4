"""The apps: programs on top of the engine and the session, never beside them. The demo and the
robot demo (`demo`, `robot_demo`), the soak (`soak/`), the bench (`bench/`: `make bench`'s
measurements and the rig probe), the bus load model (`busload`), the field recorder's capture
(`capture`), bus logs turned into traces (`log_trace`), the bus scan (`scan`), the demo joint's
FMU (`joint_fmu`) and the dashboards' screenshots (`screenshots`). They may import every layer but
the CLI, which is built on them; the scripts of tools/ call them (docs/architecture.md: the rig's
public modules).
"""
