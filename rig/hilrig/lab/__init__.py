"""labgrid's CAN resource and driver, a plugin of labgrid (its env YAML's `imports: [hilrig.lab]`):
a board farm's place then names the board's CAN interface beside its power and console, and the
scenarios take their bus from it (`hilrig.pytest_plugin.labgrid`, with `--lg-env`).

    # env.yaml
    imports: [hilrig.lab]
    targets:
      main:
        resources:
          RemotePlace: {name: joint-1}      # its NetworkCANPort comes from the exporter
        drivers:
          CANDriver: {}
          ExternalPowerDriver: {cmd_on: ..., cmd_off: ...}

`CANPort` (an interface on this machine) and `NetworkCANPort` (one on an exporter host, exported
as is by a stock `labgrid-exporter`) name the interface and its bit rate; `CANDriver` gives the
rig its python-can bus. Beside the CLI in the layers: it imports the session's `BoardInterface`,
nothing but the pytest plugin imports it, and only when labgrid is installed (`hilrig[labgrid]`).
"""

from hilrig.lab.can import CANDriver, CANPort, NetworkCANPort

__all__ = ["CANDriver", "CANPort", "NetworkCANPort"]
