"""The session: everything a run owns and must close. A private vcan bus in its own network
namespace (`netns`), the firmware process (`firmware`), the bus recorder and candump logs
(`buslog`), an in-process fake node (`fake_node`), fault injection on the bus and the process
(`faults`), a python-can bus from bus options (`canbus`), and the one builder that assembles and
closes them for every caller (`builder`). It may import the engine, the observers and every layer
below them, never the apps or the CLI.
"""
