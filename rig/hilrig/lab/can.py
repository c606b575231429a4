"""The CAN resources and their driver, registered with labgrid's target factory on import."""

from __future__ import annotations

import socket
from typing import ClassVar

import attr
import can
from labgrid.driver.common import Driver
from labgrid.factory import target_factory
from labgrid.resource.common import NetworkResource, Resource

from hilrig.session.builder import BoardInterface

_optional_int = attr.validators.optional(attr.validators.instance_of(int))


@target_factory.reg_resource
@attr.s(eq=False)
class CANPort(Resource):
    """A CAN interface on this machine: its SocketCAN name (`can0`, `vcan0`) and bit rate (None:
    as the interface is set up, e.g. `ip link set can0 type can bitrate 500000`)."""

    ifname: str = attr.ib(validator=attr.validators.instance_of(str))
    bitrate: int | None = attr.ib(default=None, validator=_optional_int)


@target_factory.reg_resource
@attr.s(eq=False)
class NetworkCANPort(NetworkResource):
    """A CAN interface on an exporter host (`host`), as a place's resource: a stock
    `labgrid-exporter` exports it with the parameters its config gives (host, ifname, bitrate)."""

    ifname: str = attr.ib(validator=attr.validators.instance_of(str))
    bitrate: int | None = attr.ib(default=None, validator=_optional_int)


def is_this_machine(host: str) -> bool:
    """Whether `host` names the machine this runs on (its bus is then reachable as is)."""
    return host in {"localhost", "127.0.0.1", "::1", socket.gethostname(), socket.getfqdn()}


@target_factory.reg_driver
@attr.s(eq=False)
class CANDriver(Driver):
    """The rig's bus on the target's CAN port. `interface`: python-can's (default socketcan);
    `channel`: the local interface to open instead of the port's own, for a bus on another host
    bridged to this machine (cannelloni, an SSH pipe: docs/labgrid.md)."""

    bindings: ClassVar[dict[str, object]] = {"port": {CANPort, NetworkCANPort}}
    interface: str = attr.ib(default="socketcan", validator=attr.validators.instance_of(str))
    channel: str | None = attr.ib(
        default=None, validator=attr.validators.optional(attr.validators.instance_of(str))
    )

    def board_interface(self) -> BoardInterface:
        """The port as the session opens a real board's bus (`hilrig.session.builder`)."""
        port = self.port
        if self.channel is None and isinstance(port, NetworkCANPort) and not is_this_machine(port.host):
            raise ValueError(
                f"the place's CAN port {port.ifname} is on host {port.host}, not this one: bridge it "
                "here (cannelloni or an SSH pipe, docs/labgrid.md) and give CANDriver the local "
                "interface as `channel`"
            )
        return BoardInterface(self.interface, self.channel or port.ifname, port.bitrate)

    @Driver.check_active
    def open_bus(self, **kwargs: object) -> can.BusABC:
        """A python-can bus on the port (`hilrig.errors.BusUnavailableError` if it does not open)."""
        interface = self.board_interface()
        return BoardInterface(
            interface.interface, interface.channel, interface.bitrate, {**interface.kwargs, **kwargs}
        ).open()
