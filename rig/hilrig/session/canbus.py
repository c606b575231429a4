"""A python-can bus from bus options: the interface, channel, bit rates and the interface's own
keyword arguments, as python-can's tools take them, with python-can's configuration for what is
not given (`bus_config`), opened with its failures in words (`open_bus`).

A bus option that cannot work on this machine (an interface not installed, for another platform,
refusing its options; an unusable configuration) is a `BusOptionError`; a bus that could open
but does not (no adapter, no such channel) a `BusUnavailableError`. python-can is imported inside
the functions: a command line that only parses stays quick (the import costs seconds in the
micro-VM).
"""

from __future__ import annotations

import errno
import time
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Self

from hilrig.errors import BusUnavailableError, ConfigurationError, one_line

if TYPE_CHECKING:
    import can

    Bus = can.BusABC
    Message = can.Message
    Listener = can.Listener

DEFAULT_INTERFACE = "socketcan"
DEFAULT_CHANNEL = "vcan0"
"""The bus when python-can's configuration names none: the rig's own virtual bus."""

# The package an interface needs beyond python-can, and python-can's extra that pulls it in.
# python-can raises "... not installed" for these; the line then says what to install.
INTERFACE_PACKAGES: dict[str, tuple[str, str]] = {
    "slcan": ("pyserial", "serial"),
    "serial": ("pyserial", "serial"),
    "robotell": ("pyserial", "serial"),
    "seeedstudio": ("pyserial", "seeedstudio"),
    "gs_usb": ("gs-usb", "gs-usb"),
    "cantact": ("cantact", "cantact"),
    "canalystii": ("canalystii", "canalystii"),
    "neovi": ("python-ics", "neovi"),
    "nixnet": ("nixnet", "nixnet"),
    "udp_multicast": ("msgpack", "multicast"),
}

# The vendor library an interface loads with ctypes when its bus opens (not a Python package).
INTERFACE_LIBRARIES: dict[str, tuple[str, str]] = {
    "pcan": ("PEAK's PCAN-Basic library (libpcanbasic.so, from peak-system.com)", "peak_usb"),
    "kvaser": ("Kvaser's CANlib (libcanlib.so, from Kvaser's linuxcan)", "kvaser_usb"),
}
"""interface -> (the library, the Linux kernel driver that serves the same adapters on socketcan)."""


class BusOptionError(ConfigurationError):
    """The bus options cannot work on this machine (the message says what to give or install)."""


@dataclass(frozen=True)
class CanFilter:
    """python-can's `can_id:can_mask` filter; `can_id~can_mask` (inverted) keeps the frames that
    do NOT match. A frame is kept when any filter of a list keeps it."""

    can_id: int
    can_mask: int
    inverted: bool = False

    def keeps(self, arbitration_id: int) -> bool:
        return ((arbitration_id ^ self.can_id) & self.can_mask == 0) != self.inverted

    def __str__(self) -> str:
        return f"{self.can_id:X}{'~' if self.inverted else ':'}{self.can_mask:X}"


def interface_names() -> frozenset[str]:
    """The interfaces python-can knows (`can.interfaces.VALID_INTERFACES`)."""
    from can.interfaces import VALID_INTERFACES

    return frozenset(VALID_INTERFACES)


def option_value(text: str) -> Any:
    """An interface option's value typed as python-can's `can.logger --bus-kwargs` types it
    ('1' -> 1, '0.5' -> 0.5, 'True' -> True)."""
    from can.util import cast_from_string

    return cast_from_string(text)


def describe_bus(interface: str, channel: object | None) -> str:
    """'socketcan channel vcan0'."""
    return f"{interface} channel {channel}" if channel is not None else interface


def bus_config(given: Mapping[str, Any], filters: list[CanFilter] | None = None) -> dict[str, Any]:
    """The keyword arguments of `can.Bus`: `given` (the options named) first, then python-can's
    configuration (`can.util.load_config`: ~/.canrc or can.ini, CAN_INTERFACE, CAN_CHANNEL,
    CAN_BITRATE, CAN_CONFIG), then socketcan on vcan0 when nothing names an interface. Plain
    `filters` go to the kernel or adapter; with an inverted one among them the caller filters.
    A configured bit rate given as text stays text: the caller's parser reads it."""
    import can

    given = dict(given)
    if given.get("data_bitrate") is not None:
        given.setdefault("fd", True)
    if filters and not any(f.inverted for f in filters):
        given["can_filters"] = [{"can_id": f.can_id, "can_mask": f.can_mask} for f in filters]
    try:
        try:
            config = dict(can.util.load_config(config=given))
        except can.CanInterfaceNotImplementedError:
            if "interface" in given or _configured_interface():
                raise
            config = dict(can.util.load_config(config={**given, "interface": DEFAULT_INTERFACE}))
    except (can.CanInterfaceNotImplementedError, ValueError, TypeError) as error:
        raise BusOptionError(
            f"python-can's configuration (~/.canrc, can.ini, CAN_INTERFACE, CAN_CONFIG...) is unusable: "
            f"{one_line(error)}; give --interface and --channel, or fix it"
        ) from None
    if config.get("channel") is None and config["interface"] == DEFAULT_INTERFACE:
        config["channel"] = DEFAULT_CHANNEL
    return config


def _configured_interface() -> bool:
    """Whether any of python-can's configuration sources names an interface."""
    import can

    sources = (can.rc, can.util.load_environment_config(), can.util.load_file_config())
    return any(source.get("interface") or source.get("bustype") for source in sources)


def open_bus(config: Mapping[str, Any]) -> can.BusABC:
    """`can.Bus(**config)` (a `bus_config`), its receive queue deepened. An interface that cannot
    work on this machine (not installed, wrong platform, wrong options) is a BusOptionError; one
    that could but does not open (no adapter, no such channel) a BusUnavailableError. The caller
    shuts the bus down."""
    import can

    interface = config["interface"]
    channel = config.get("channel")
    try:
        bus = can.Bus(ignore_config=True, **config)
    except (can.CanInterfaceNotImplementedError, ImportError) as error:
        raise BusOptionError(
            f"cannot use the {interface} interface: {_missing_hint(interface, error)}"
        ) from error
    except TypeError as error:  # the backend's constructor refused the options
        raise BusOptionError(
            f"the {interface} interface refused its options: {one_line(error)}; give them with "
            "--bus-kwargs KEY=VALUE (see python-can's page of that interface)"
        ) from error
    except Exception as error:  # backends raise what they like: the adapter's problem, in words
        library = _missing_library(interface, error)
        if library is not None:
            raise BusOptionError(f"cannot use the {interface} interface: {library}") from error
        raise BusUnavailableError(
            f"cannot open {describe_bus(interface, channel)}: {one_line(error)}"
            f"{_bus_hint(interface, channel, error)}"
        ) from error
    from hilrig.session.netns import deepen_receive_queue

    deepen_receive_queue(bus)  # a recorder or watcher descheduled for a moment loses nothing
    return bus


def _missing_hint(interface: str, error: BaseException) -> str:
    """python-can's reason, and for a package that is not installed, how to install it."""
    reason = one_line(error)
    package = INTERFACE_PACKAGES.get(interface)
    missing = isinstance(error, ImportError) or any(
        words in reason.lower() for words in ("not installed", "install it", "no module named")
    )
    if package is None or not missing:
        return reason
    name, extra = package
    return (
        f"it needs the {name} package, which is not installed: pip install {name} "
        f"(or pip install 'python-can[{extra}]')"
    )


def _missing_library(interface: str, error: BaseException) -> str | None:
    """'it needs ..., which is not installed' when the interface's vendor library is missing:
    python-can's pcan says 'library not found', its kvaser leaves canlib's functions undefined
    (a NameError); None for any other failure."""
    known = INTERFACE_LIBRARIES.get(interface)
    reason = one_line(error).lower()
    if known is None or not (isinstance(error, NameError) or "library not found" in reason):
        return None
    library, driver = known
    return f"it needs {library}, which is not installed; or use -i socketcan (the kernel's {driver} driver)"


def _bus_hint(interface: str, channel: object | None, error: BaseException) -> str:
    code = _errno_of(error)
    if interface == "socketcan":
        if code == errno.EAFNOSUPPORT:
            return (
                "; this kernel has no SocketCAN: run inside `tools/with-vcan -- ...` or pick "
                "another --interface"
            )
        if code == errno.ENODEV or "No such device" in str(error):
            return f"; no interface {channel} here: `ip link show` lists them, `make vcan` creates vcan0"
        return ""
    return f"; is the {interface} adapter plugged in and its driver installed?"


def _errno_of(error: BaseException | None) -> int | None:
    while error is not None:
        if isinstance(error, OSError) and error.errno is not None:
            return error.errno
        for attr in ("error_code",):
            code = getattr(error, attr, None)
            if isinstance(code, int):
                return code
        error = error.__cause__ or error.__context__
    return None


def received(bus: can.BusABC, duration_s: float, *, poll_s: float = 0.2) -> Iterator[can.Message]:
    """The frames `bus` receives for `duration_s` (wall time, a live bus's own); Ctrl-C ends it
    early."""
    deadline = time.monotonic() + duration_s
    try:
        while (left := deadline - time.monotonic()) > 0:
            message = bus.recv(timeout=min(left, poll_s))
            if message is not None:
                yield message
    except KeyboardInterrupt:
        return


class Notified:
    """python-can's notifier on `bus` for `listeners` (a context manager: stopped on exit)."""

    def __init__(self, bus: can.BusABC, listeners: list[Any]) -> None:
        import can

        self._notifier = can.Notifier(bus, listeners)

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.stop()

    def stop(self) -> None:
        self._notifier.stop()


def paced(frames: Iterator[can.Message], *, timestamps: bool) -> Iterator[can.Message]:
    """`frames` at their recorded pace (python-can's MessageSync; `timestamps=False`: at once)."""
    import can

    return iter(can.MessageSync(frames, timestamps=timestamps, gap=0.0))
