"""Private CAN buses: one network namespace per scenario, each with its own ``vcan0``.

Scenarios that run in parallel must never see each other's frames. A vcan interface lives in
a network namespace, so each scenario gets a namespace of its own with a ``vcan0`` inside.
Processes (the firmware) are started inside it with ``ip netns exec``; the rig's own sockets
are opened inside it by switching the calling thread into the namespace just long enough to
create the socket (a socket stays bound to the namespace it was created in).

Needs root (CAP_SYS_ADMIN) and a kernel with vcan: natively on such a host, or inside the
guest of ``hilrig bus`` (``tools/with-vcan`` in the checkout).
"""

from __future__ import annotations

import contextlib
import itertools
import os
import shutil
import subprocess
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, Self

import can

from hilrig.errors import BusUnavailableError
from hilrig.wire.transport import RECEIVE_QUEUE_BYTES, setns_network, socketcan_socket
from hilrig.wire.transport import deepen_receive_queue as deepen_socket_queue

_names = itertools.count()


NEEDS = "needs root and a kernel with vcan for its private bus"
"""What a private bus needs, said once for every caller's error (`require_private_buses`)."""


def private_buses_supported() -> bool:
    """True when this process may create network namespaces with a vcan inside."""
    return os.geteuid() == 0 and shutil.which("ip") is not None


def require_private_buses(
    what: str, how: str = "run it through `hilrig bus -- ...` (a checkout: tools/with-vcan) or on a vcan host"
) -> None:
    """BusUnavailableError "<what> needs root and a kernel with vcan ...: <how>" unless this
    process may make private buses."""
    if not private_buses_supported():
        raise BusUnavailableError(f"{what} {NEEDS}: {how}")


def _ip(*args: str, batch: str | None = None) -> None:
    """`ip ARGS`; with `batch`, `ip ARGS -batch -` running those commands, one a line."""
    argv = ["ip", *args, *(["-batch", "-"] if batch is not None else [])]
    result = subprocess.run(argv, input=batch, capture_output=True, text=True, check=False)
    if result.returncode != 0:
        spelled = " ".join(argv[1:]) + (f" <<< {batch.strip()!r}" if batch is not None else "")
        raise BusUnavailableError(
            f"`ip {spelled}` failed: {result.stderr.strip()} "
            f"(a session {NEEDS}: run it through `hilrig bus -- ...`)"
        )


class PrivateBus:
    """A network namespace with its own ``vcan0``, removed again on close.

    Use as a context manager::

        with PrivateBus() as bus:
            firmware = bus.popen(["build/bin/joint-firmware", "--can", "vcan0"])
            with bus.open() as can_bus:
                ...
    """

    def __init__(self, name: str | None = None, channel: str = "vcan0") -> None:
        self.name = name or f"hil-{os.getpid()}-{next(_names)}"
        self.channel = channel
        self._created = False

    def __enter__(self) -> Self:
        self.create()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def create(self) -> None:
        _ip("netns", "add", self.name)
        self._created = True
        try:
            # One process for the three (in the VM of the bus stage a process start is ~0.1 s).
            vcan = self.channel
            _ip("-n", self.name, batch=f"link add dev {vcan} type vcan\nlink set up {vcan}\nlink set up lo\n")
        except BusUnavailableError:
            self.close()
            raise

    def close(self) -> None:
        if self._created:
            # Deleting the namespace removes its vcan0; processes still inside keep it alive
            # until they exit, so callers stop their processes first.
            subprocess.run(["ip", "netns", "delete", self.name], capture_output=True, check=False)
            self._created = False

    @contextlib.contextmanager
    def entered(self) -> Iterator[None]:
        """Run the body with the calling thread inside the namespace."""
        with (
            open("/proc/thread-self/ns/net", "rb") as home,
            self.namespace_file.open("rb") as target,
        ):
            setns_network(target.fileno())
            try:
                yield
            finally:
                setns_network(home.fileno())

    def open(self, **kwargs: Any) -> can.BusABC:
        """A python-can SocketCAN bus on this namespace's vcan0, with a deep receive queue."""
        with self.entered():
            bus = can.Bus(interface="socketcan", channel=self.channel, **kwargs)
        deepen_receive_queue(bus)
        return bus

    @property
    def namespace_file(self) -> Path:
        """The namespace's file (what `setns` takes): a process moves itself in with it."""
        return Path("/var/run/netns") / self.name

    def command(self, argv: Sequence[str]) -> list[str]:
        """``argv`` prefixed so that it runs inside the namespace."""
        return ["ip", "netns", "exec", self.name, *argv]

    def popen(self, argv: Sequence[str], **kwargs: Any) -> subprocess.Popen[Any]:
        return subprocess.Popen(self.command(argv), **kwargs)


def deepen_receive_queue(bus: can.BusABC, size: int = RECEIVE_QUEUE_BYTES) -> int:
    """Raise a SocketCAN bus's receive queue to `size` (`hilrig.wire.transport`); returns what the
    kernel granted (0: not a SocketCAN bus)."""
    sock = socketcan_socket(bus)
    return deepen_socket_queue(sock, size) if sock is not None else 0
