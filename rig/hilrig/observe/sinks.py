"""Where a trace goes: a .rrd file, a spawned viewer, a running one, or a served web viewer
(`TraceSink`, spelled 'rrd:PATH', 'spawn[:PORT]', 'connect[:URL]', 'web[:PORT[:GRPC_PORT]]'), the
live sinks $HIL_TRACE names, and the levels of the text log.
"""

from __future__ import annotations

import enum
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import quote

from hilrig.errors import RigError, unknown_name

APPLICATION_ID = "hilrig"
"""Rerun application id of every trace; blueprints are saved for this id."""
LIVE_LATENCY_S = 1.0
"""A live sink (spawned, connected or served viewer) also gets a batch whenever this much wall
time passed since the last one, so what it shows is never more than about a second old."""


class Severity(enum.StrEnum):
    """Text log levels, spelled as Rerun's TextLogLevel."""

    INFO = "INFO"
    WARN = "WARN"
    ERROR = "ERROR"


# --- Sinks ----------------------------------------------------------------------------------
class SinkKind(enum.StrEnum):
    RRD = "rrd"
    SPAWN = "spawn"
    CONNECT = "connect"
    WEB = "web"


DEFAULT_GRPC_PORT = 9876
DEFAULT_WEB_PORT = 9090
VIEWER_BIND_ADDRESS = "127.0.0.1"
"""Where `open_trace(..., web=True)` serves: this machine only (forward the ports to share it)."""


@dataclass(frozen=True)
class TraceSink:
    """Where a trace goes. Several can be combined: `Tracer([TraceSink.rrd(p), TraceSink.spawn()])`.

    On the command line: `TraceSink.parse("rrd:out/trace.rrd")`, "spawn", "connect",
    "connect:rerun+http://host:9876/proxy", "web", "web:9090".
    """

    kind: SinkKind
    path: Path | None = None
    url: str | None = None
    port: int | None = None

    @classmethod
    def rrd(cls, path: str | Path) -> TraceSink:
        """A `.rrd` file (parent folders are created)."""
        return cls(SinkKind.RRD, path=Path(path))

    @classmethod
    def spawn(cls, port: int = DEFAULT_GRPC_PORT) -> TraceSink:
        """Spawn a native viewer listening on `port` (or reuse one already there) and stream to it."""
        return cls(SinkKind.SPAWN, port=port)

    @classmethod
    def connect(cls, url: str = f"rerun+http://127.0.0.1:{DEFAULT_GRPC_PORT}/proxy") -> TraceSink:
        """Stream to a running viewer or `rerun --serve-grpc` (e.g. the compose `viewer` service)."""
        return cls(SinkKind.CONNECT, url=url)

    @classmethod
    def serve_web(cls, port: int = DEFAULT_WEB_PORT, grpc_port: int = DEFAULT_GRPC_PORT) -> TraceSink:
        """Serve the web viewer on http://localhost:`port` (no display needed); the data is kept in
        an in-process gRPC server on `grpc_port` for as long as this process lives."""
        return cls(SinkKind.WEB, port=port, url=f"{grpc_port}")

    @classmethod
    def parse(cls, spec: str) -> TraceSink:
        """'rrd:PATH' | 'spawn[:PORT]' | 'connect[:URL]' | 'web[:PORT[:GRPC_PORT]]'."""
        kind, _, arg = spec.partition(":")
        try:
            sink_kind = SinkKind(kind)
        except ValueError:
            raise unknown_name("trace sink", kind, [k.value for k in SinkKind]) from None
        if sink_kind is SinkKind.RRD:
            if not arg:
                raise ValueError("trace sink 'rrd' needs a path: rrd:out/trace.rrd")
            return cls.rrd(arg)
        if sink_kind is SinkKind.SPAWN:
            return cls.spawn(_port(arg)) if arg else cls.spawn()
        if sink_kind is SinkKind.CONNECT:
            return cls.connect(arg) if arg else cls.connect()
        if not arg:
            return cls.serve_web()
        web_port, _, grpc_port = arg.partition(":")
        if grpc_port:
            return cls.serve_web(_port(web_port), _port(grpc_port))
        return cls.serve_web(_port(web_port))

    def __str__(self) -> str:
        """The spelling `parse` reads: 'rrd:out/trace.rrd', 'spawn:9876', 'web:9090', 'connect:URL'."""
        if self.kind is SinkKind.RRD:
            return f"rrd:{self.path}"
        if self.kind is SinkKind.CONNECT:
            return f"connect:{self.url}"
        if self.kind is SinkKind.WEB:
            return f"web:{self.port}:{self.url}"
        return f"{self.kind.value}:{self.port}"


def _port(text: str) -> int:
    """A TCP port, 1..65535; ValueError otherwise."""
    port = int(text)
    if not 1 <= port <= 65535:
        raise ValueError(f"port {port} is out of range 1..65535")
    return port


LIVE_TRACE_ENV = "HIL_TRACE"
"""Live sinks for every traced run (comma-separated, as `TraceSink.parse` reads them, no rrd):
`hilrig sim` takes them as its default --viewer and pytest scenarios stream to them, beside the
trace.rrd they always write. The compose file sets it to the viewer service's address."""


def parse_live_sink(text: str) -> TraceSink:
    """A live sink (spawn, web or connect); ValueError for a file sink or a bad spelling."""
    try:
        sink = TraceSink.parse(text)
    except (ValueError, RigError) as error:  # an unknown kind, a port that is no number
        raise ValueError(
            f"{text!r}: {error} (spawn[:PORT], web[:PORT[:GRPC_PORT]] or connect[:URL])"
        ) from None
    if sink.kind is SinkKind.RRD:
        raise ValueError(f"{text!r}: the trace file is always written; name a live sink here")
    return sink


def live_sinks_from_environment(environ: Mapping[str, str] = os.environ) -> list[TraceSink]:
    """The live sinks $HIL_TRACE names (none when unset); ValueError naming the variable."""
    sinks = []
    for part in filter(None, (p.strip() for p in environ.get(LIVE_TRACE_ENV, "").split(","))):
        try:
            sinks.append(parse_live_sink(part))
        except ValueError as error:
            raise ValueError(f"${LIVE_TRACE_ENV}: {error}") from None
    return sinks


def default_latency(sinks: Sequence[TraceSink]) -> float | None:
    """How old the newest traced cycle may get before a batch goes out: LIVE_LATENCY_S when a
    viewer watches (spawned, connected or served), None (whole batches only) for files alone."""
    return LIVE_LATENCY_S if any(sink.kind is not SinkKind.RRD for sink in sinks) else None


def web_viewer_url(web_port: int = DEFAULT_WEB_PORT, grpc_port: int = DEFAULT_GRPC_PORT) -> str:
    """The page to open for a trace served by `open_trace(..., web=True)`: the web viewer, told
    where the gRPC server with the data is (the browser connects to both ports)."""
    data = quote(f"rerun+http://127.0.0.1:{grpc_port}/proxy", safe="")
    return f"http://127.0.0.1:{web_port}/?url={data}"
