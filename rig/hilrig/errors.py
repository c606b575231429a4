"""The rig's exceptions: one shallow tree rooted in ``RigError``, with built-in parents where
they fit, so callers can catch ``TimeoutError`` or ``ValueError`` without knowing the rig."""

from __future__ import annotations

import difflib
from collections.abc import Iterable


def one_line(error: BaseException) -> str:
    """The error's message on one line (what the command line prints); its type if it has none.
    A plain OSError about a file reads 'FILE: Permission denied', not '[Errno 13] ...'."""
    plain = isinstance(error, OSError) and type(error).__module__ == "builtins"
    if plain and error.filename and error.strerror:
        return f"{error.filename}: {error.strerror}"
    return " ".join(str(error).split()) or type(error).__name__


class RigError(Exception):
    """Base of every error the rig raises on purpose."""


class ConfigurationError(RigError, ValueError):
    """The project's configuration ($HIL_TABLE, a pytest.ini) names a file that is not there or
    cannot be read (the message says where it is named)."""


class PlantMapError(ConfigurationError):
    """A plant map (an FMU's variables tied to a board's HIL I/O) does not fit its FMU or its
    table: the message names the map, the entry and what to change."""


class BusUnavailableError(RigError, OSError):
    """The CAN bus (or a private namespace bus) cannot be opened or created."""


class FieldNameError(RigError, KeyError):
    """A field name that the protocol table does not define (the message lists close matches)."""

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0]) if self.args else ""


class LockstepError(RigError, TimeoutError):
    """A lockstep cycle did not complete: a PDO of that cycle is missing or late."""


class HostStarvedError(RigError, TimeoutError):
    """A lockstep wait ended because the host gave the firmware too little CPU for too long, not
    because the firmware misbehaved (`hilrig.engine.lockstep.HangGuard`): no verdict on the firmware."""


class RealTimeError(RigError, TimeoutError):
    """In real-time mode the node's TPDOs stopped arriving (the message says since when)."""


class FirmwareError(RigError, RuntimeError):
    """The firmware process failed to start, crashed, or stopped answering."""


class SdoAbortError(RigError, RuntimeError):
    """The node answered an SDO request with an abort code (explained in words).

    ``abort_code`` is the CiA 301 code on the wire, so a test can compare against it.
    """

    def __init__(self, message: str, abort_code: int) -> None:
        super().__init__(message)
        self.abort_code = abort_code


class NodeSilentError(RigError, TimeoutError):
    """The node sent no boot-up, heartbeat or SDO answer within the start-up bound."""


class IdentityMismatchError(NodeSilentError):
    """The node answering on the board's node id has another 0x1018 vendor id or product code than
    the table: the board itself is not there (a NodeSilentError to those who wait for it).
    ``actual`` and ``expected`` are (vendor id, product code); ``table`` is the table's file."""

    def __init__(
        self, message: str, *, node_id: int, actual: tuple[int, int], expected: tuple[int, int], table: str
    ) -> None:
        super().__init__(message)
        self.node_id = node_id
        self.actual = actual
        self.expected = expected
        self.table = table


class SdoTimeoutError(RigError, TimeoutError):
    """The node did not answer an SDO request in time (no abort code either)."""


class PdoMappingError(RigError, ValueError):
    """The node's PDO configuration lacks something the rig relies on (the message says what)."""


class NoValueError(RigError, LookupError):
    """A known name that has no value yet: nothing received, or not carried by any PDO."""


class ScenarioTimeoutError(RigError, TimeoutError):
    """A condition a scenario waited for did not hold within its simulation-time bound."""


class FieldAccessError(RigError, ValueError):
    """A field the rig cannot set that way (e.g. a raw sensor input the physics computes)."""


class LogFileError(RigError, ValueError):
    """A bus log whose content python-can cannot read: garbled or cut off (the file is named)."""


class LogFormatError(LogFileError):
    """A bus log in a format python-can does not read, or not without a package that is not
    installed (the message lists the formats, or says what to install)."""


def unknown_name(what: str, name: str, known: Iterable[str]) -> FieldNameError:
    """FieldNameError "no <what> named 'x'; did you mean 'y'?" with up to three close matches."""
    matches = difflib.get_close_matches(name, list(known), n=3, cutoff=0.6)
    hint = f"; did you mean {' or '.join(repr(m) for m in matches)}?" if matches else ""
    return FieldNameError(f"no {what} named {name!r}{hint}")
