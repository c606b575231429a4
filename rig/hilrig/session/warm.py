"""One warm server for a session's helper processes: multiprocessing's forkserver, started once
per process with the modules its children need already imported (`preload`), so a helper process
(the bus recorder; in tests, a `hilrig` command) starts at once instead of in a fresh
interpreter. Inside the software-emulated VM a fresh interpreter importing python-can costs
seconds, and a scenario starts several such helpers.

Each child is forked from the server, not from the caller: it has the server's imports and none
of the caller's threads, locks or open buses. What it needs from the caller it is given
explicitly (the environment, a network namespace to move into, where its output goes).
"""

from __future__ import annotations

import multiprocessing
import multiprocessing.context
import multiprocessing.forkserver
from pathlib import Path

_preload: list[str] = ["can", "hilrig.wire.transport", "hilrig.session.buslog"]


def preload(*modules: str) -> None:
    """Have the server import these as well; only before it started (`start`), else no effect
    on the running server (its children then import them themselves)."""
    _preload.extend(m for m in modules if m not in _preload)


def start() -> None:
    """Start the server now, in the background (its imports overlap with the caller's work).
    Idempotent."""
    multiprocessing.set_forkserver_preload(list(_preload))
    multiprocessing.forkserver.ensure_running()


def context() -> multiprocessing.context.ForkServerContext:
    """The context to make helper processes with (`context().Process(...)`), server started."""
    start()
    forkserver = multiprocessing.get_context("forkserver")
    assert isinstance(forkserver, multiprocessing.context.ForkServerContext)
    return forkserver


def enter_namespace(namespace_file: Path | None) -> None:
    """In a child: move this process into the network namespace `namespace_file` (None: stay)."""
    if namespace_file is None:
        return
    from hilrig.wire.transport import setns_network

    with namespace_file.open("rb") as namespace:
        setns_network(namespace.fileno())


__all__ = ["context", "enter_namespace", "preload", "start"]
