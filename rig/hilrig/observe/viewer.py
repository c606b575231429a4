"""Opening a saved trace: a native viewer spawned, or the web viewer served, with a dashboard."""

from __future__ import annotations

import contextlib
import os
import socket
import subprocess
import sys
import tempfile
from pathlib import Path

from hilrig.observe.blueprints import save_blueprint
from hilrig.observe.sinks import DEFAULT_GRPC_PORT, DEFAULT_WEB_PORT, VIEWER_BIND_ADDRESS, web_viewer_url


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
    blueprint: str = "overview",
    *,
    web: bool = False,
    web_port: int = DEFAULT_WEB_PORT,
    grpc_port: int = DEFAULT_GRPC_PORT,
    launch: bool = True,
) -> ViewerProcess | list[str]:
    """Open a saved trace in a native viewer (spawned), or serve it to the web viewer (web=True),
    with the named blueprint active.

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
    rbl = Path(tempfile.mkdtemp(prefix="hilrig-blueprint-")) / f"{blueprint}.rbl"
    save_blueprint(blueprint, rbl)
    command = [sys.executable, "-m", "rerun"]
    if web:
        command += ["--web-viewer", "--web-viewer-port", str(web_port)]
    command += [str(path), str(rbl)]
    if web:
        # Without --port the data would go to 9876 whatever else listens there (spawn, compose).
        command += ["--port", str(grpc_port), "--bind", VIEWER_BIND_ADDRESS]
    if not launch:
        return command
    if web:
        _check_port_free(web_port, "web viewer")
        _check_port_free(grpc_port, "gRPC")
    process = ViewerProcess(command, process_group=0)
    if web:
        process.url = web_viewer_url(web_port, grpc_port)
        print(f"web viewer: open {process.url}", flush=True)
    return process
