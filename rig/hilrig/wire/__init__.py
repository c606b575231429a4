"""The wire: the one place that opens raw CAN sockets and packs frames. The raw-socket exchange
(`transport`, with its C part `_wire.c`), the frame link over a raw socket or python-can's Bus, the
PDO codecs compiled from a node's PDO configuration, the node's SDO, NMT, EMCY and heartbeat
traffic over canopen (`node`), and the NMT commands and SYNC of a board with no rig (`master`).
It imports only the base of hilrig (`errors`, `table`, `resources`, `observe.paths`) and
`boardproto`.
"""
