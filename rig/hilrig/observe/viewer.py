"""Opening a saved trace: a native viewer spawned, or the web viewer served, with a dashboard."""

from __future__ import annotations

import contextlib
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import TYPE_CHECKING

from hilrig.observe import streams
from hilrig.observe.blueprints import load_blueprint, save_blueprint
from hilrig.observe.sinks import (
    APPLICATION_ID,
    DEFAULT_GRPC_PORT,
    DEFAULT_WEB_PORT,
    VIEWER_BIND_ADDRESS,
    web_viewer_url,
)

if TYPE_CHECKING:
    import rerun.blueprint as rrb

SERVE_TIMEOUT_S = 120.0
"""Hang guard for a served viewer's ports to listen (a loaded machine starts rerun slowly)."""


class ViewerProcess(subprocess.Popen[bytes]):
    """A viewer started by `open_trace`, in a process group of its own.

    `python -m rerun` is only a wrapper that runs the real binary and does not pass signals on,
    so `terminate()`, `kill()` and `send_signal()` signal the whole group: otherwise the binary
    would be left serving after its wrapper is gone. `url`: what to open in a browser (web=True).
    """

    url: str | None = None

    def send_signal(self, sig: int) -> None:
        self.poll()
        if self.returncode is None:  # once reaped, the group id may belong to someone else
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.pid, sig)


def _check_port_free(port: int, what: str) -> None:
    # Rerun 0.41 does not fail on a port in use: it spins without serving anything. SO_REUSEADDR:
    # only a listener counts, not the TIME_WAIT connections of a viewer that just ended.
    with socket.socket() as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((VIEWER_BIND_ADDRESS, port))
        except OSError as error:
            raise OSError(f"{what} port {port} is in use ({error.strerror}): choose another one") from None


def open_trace(
    path: str | Path,
    blueprint: str | rrb.Blueprint = "overview",
    *,
    web: bool = False,
    web_port: int = DEFAULT_WEB_PORT,
    grpc_port: int = DEFAULT_GRPC_PORT,
    launch: bool = True,
) -> ViewerProcess | list[str]:
    """Open a saved trace in a native viewer (spawned), or serve it to the web viewer (web=True),
    with the blueprint active (one built for the trace's board, or the one named, for the
    default table).

    web=True serves the viewer page on 127.0.0.1:`web_port` and the recording from a gRPC
    server on 127.0.0.1:`grpc_port`; the page to open is printed and in `process.url`
    (`web_viewer_url`). No display is needed; from another machine, forward both ports
    (`ssh -L 9090:127.0.0.1:9090 -L 9876:127.0.0.1:9876 host`).

    Returns the viewer process (the caller owns it: `terminate()` ends the whole viewer);
    launch=False returns the command instead.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"no trace at {path}")
    command = [sys.executable, "-m", "rerun"]
    if web:
        # The trace is not named here but sent in once the server listens (`send_to_viewer`):
        # rerun 0.41 serving a file it loaded keeps a thread polling the finished loader, a
        # whole core for as long as it serves. Without --port the data would go to 9876
        # whatever else listens there (spawn, compose).
        command += ["--web-viewer", "--web-viewer-port", str(web_port)]
        command += ["--port", str(grpc_port), "--bind", VIEWER_BIND_ADDRESS]
    else:
        name = blueprint if isinstance(blueprint, str) else "dashboard"
        rbl = Path(tempfile.mkdtemp(prefix="hilrig-blueprint-")) / f"{name}.rbl"
        save_blueprint(blueprint, rbl)
        command += [str(path), str(rbl)]
    if not launch:
        return command
    if web:
        _check_port_free(web_port, "web viewer")
        _check_port_free(grpc_port, "gRPC")
    process = ViewerProcess(command, process_group=0)
    if web:
        try:
            wait_until_listening(grpc_port, process, SERVE_TIMEOUT_S)
            # The server keeps the recording, whole, for every page that connects.
            built = load_blueprint(blueprint) if isinstance(blueprint, str) else blueprint
            send_to_viewer(grpc_port, built, trace=path)
        except BaseException:
            process.terminate()
            process.wait()
            raise
        process.url = web_viewer_url(web_port, grpc_port)
        print(f"web viewer: open {process.url}", flush=True)
    return process


def send_to_viewer(
    grpc_port: int,
    blueprint: rrb.Blueprint,
    *,
    recording_id: str | None = None,
    trace: Path | None = None,
) -> None:
    """Into a served viewer's gRPC server, which passes it on to every page: `trace` first if
    given (the file's own recording), then `blueprint` made the active and the default one.
    The stream sends no recording of its own (send_properties=False: no empty second source);
    `recording_id`: the shown recording's, where a page already shows one."""
    with streams.live():
        _send(grpc_port, blueprint, recording_id, trace)
    streams.release()  # the stream is let go of


def _send(grpc_port: int, blueprint: rrb.Blueprint, recording_id: str | None, trace: Path | None) -> None:
    import rerun as rr

    stream = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id, send_properties=False)
    stream.connect_grpc(f"rerun+http://{VIEWER_BIND_ADDRESS}:{grpc_port}/proxy")
    try:
        if trace is not None:
            rr.log_file_from_path(trace, recording=stream)
        streams.send_blueprint(stream, blueprint, make_active=True, make_default=True)
        stream.flush()
    finally:
        stream.disconnect()


def wait_until_listening(port: int, process: subprocess.Popen[bytes], timeout_s: float) -> None:
    """Until something accepts connections on 127.0.0.1:`port`; OSError if `process` exits
    first or `timeout_s` passes (a hang guard)."""
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=1).close()
            return
        except OSError:
            pass
        # Between attempts, wait on the viewer process itself: a viewer that dies ends the wait
        # at once instead of after a blind pause.
        try:
            returncode: int | None = process.wait(timeout=0.1)
        except subprocess.TimeoutExpired:
            returncode = None
        if returncode is not None:
            raise OSError(f"the viewer exited with {returncode} before serving port {port}")
        if time.monotonic() > deadline:
            raise OSError(f"Expected the viewer on port {port} within {timeout_s:.0f} s")
