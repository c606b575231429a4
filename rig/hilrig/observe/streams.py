"""Rerun's streams, let go of once used: the one place the rig frees what Rerun keeps of them.

Rerun keeps every stream made in the process, with its two threads (a batcher and a sender),
until the stream is dropped *and* a sweep (`flush_and_cleanup_orphaned_recordings`, which only
`rr.init` calls, and the rig never does) removes it. So whoever ends a stream calls `release()`
once it has let go of it (`Tracer.close`, `write_comparison`, `send_to_viewer`).

The sweep flushes every stream of the process and waits for each, which a viewer that cannot
be reached would hold up or fail. So a stream to a viewer over gRPC is made inside `live()`
(or between `go_live` and `end_live`), and while one is, `release()` sweeps nothing: what it
would have freed goes with a later sweep. The sweep also clears Rerun's global recording, which
the rig never sets.

Blueprints go through `send_blueprint` here, never `RecordingStream.send_blueprint`: Rerun's
own makes a blueprint stream its own memory sink holds on to, which no sweep frees.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Iterator
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import rerun as rr
    import rerun.blueprint as rrb

_lock = threading.Lock()  # held by a sweep: no stream goes live while one runs
_live = 0  # streams to a viewer over gRPC, open now
_serving: list[rr.RecordingStream] = []  # recordings a served web viewer shows until the process exits


def go_live() -> None:
    """A stream to a viewer over gRPC is opening: no sweep until `end_live`."""
    global _live
    with _lock:
        _live += 1


def end_live() -> None:
    """The stream `go_live` announced is disconnected (or kept serving: `keep_serving`)."""
    global _live
    with _lock:
        if _live < 1:
            raise RuntimeError("end_live() without go_live()")
        _live -= 1


@contextlib.contextmanager
def live() -> Iterator[None]:
    """For the life of a short stream to a viewer over gRPC (`go_live`, `end_live`)."""
    go_live()
    try:
        yield
    finally:
        end_live()


def keep_serving(recording: rr.RecordingStream) -> None:
    """Keep `recording` for a served web viewer until the process exits (dropped, its gRPC
    server would stop), its file sinks finished now: each .rrd complete, its footer written."""
    from rerun import bindings

    bindings.finalize_deferred_sinks(recording=recording.to_native())
    with _lock:
        _serving.append(recording)


def release() -> bool:
    """Free what Rerun keeps of the streams already let go of (disconnected and dropped). False,
    sweeping nothing, while a stream to a viewer is live (`live`)."""
    from rerun import bindings

    with _lock:
        if _live:
            return False
        bindings.flush_and_cleanup_orphaned_recordings()
    return True


def send_blueprint(
    recording: rr.RecordingStream, blueprint: rrb.BlueprintLike, *, make_active: bool, make_default: bool
) -> None:
    """`recording.send_blueprint(...)`, through a blueprint stream disconnected once sent, so
    that `release()` frees it (built as rerun 0.41's `create_in_memory_blueprint` builds it)."""
    import rerun as rr
    from rerun import bindings

    application_id = recording.get_application_id()
    if application_id is None:
        raise ValueError("the recording has no application id")
    stream = rr.RecordingStream._from_native(
        bindings.new_blueprint(
            application_id=application_id, make_default=False, make_thread_default=False, default_enabled=True
        )
    )
    try:
        stream.set_time("blueprint", sequence=0)
        blueprint.to_blueprint()._log_to_stream(stream)
        storage = stream.memory_recording().storage
        bindings.send_blueprint(storage, make_active, make_default, recording=recording.to_native())
    finally:
        stream.disconnect()  # its memory sink, which held the stream, is let go of


__all__ = ["end_live", "go_live", "keep_serving", "live", "release", "send_blueprint"]
