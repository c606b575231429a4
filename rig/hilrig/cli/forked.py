"""`hilrig` commands run the way a test wants them: each in a process of its own, on a bus's
network namespace, with its exit code, stdout and stderr, as `subprocess.run` of the console
script gives them, but forked from the warm server (`hilrig.session.warm`) that has the CLI and
its libraries imported. The console script is `sys.exit(hilrig.cli.main())`; what runs here is
that same `main`, in a fresh process, so a command's own start-up, signals and exit are its own.
A scenario in the emulated VM runs a dozen commands, each a fresh interpreter importing canopen
otherwise.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path

CLI_PRELOAD = ("canopen", "can", "hilrig.cli")
"""What the warm server imports for commands (`warm.preload(*CLI_PRELOAD)` before it starts)."""


def run(
    argv: Sequence[str],
    *,
    namespace_file: Path | None = None,
    env: Mapping[str, str] | None = None,
    timeout_s: float | None = None,
) -> subprocess.CompletedProcess[str]:
    """`hilrig ARGV` in a process forked from the warm server, inside `namespace_file`'s
    network namespace (None: this one), with `env` (default: this process's environment) and
    this process's working directory. Raises subprocess.TimeoutExpired (after killing it) when
    it runs longer than `timeout_s`."""
    from hilrig.session import warm

    context = warm.context()
    with tempfile.TemporaryDirectory(prefix="hilrig-run-") as scratch:
        out, err = Path(scratch) / "stdout", Path(scratch) / "stderr"
        environment = dict(os.environ if env is None else env)
        process = context.Process(
            target=_command,
            args=(list(argv), namespace_file, environment, os.getcwd(), out, err),
            name=f"hilrig {' '.join(argv)}",
        )
        process.start()
        process.join(timeout_s)
        if process.exitcode is None:
            process.kill()
            process.join()
            raise subprocess.TimeoutExpired(["hilrig", *argv], timeout_s or 0.0, _text(out), _text(err))
        return subprocess.CompletedProcess(["hilrig", *argv], process.exitcode, _text(out), _text(err))


def _text(path: Path) -> str:
    return path.read_text(errors="replace") if path.exists() else ""


def _command(
    argv: list[str], namespace_file: Path | None, env: dict[str, str], cwd: str, out: Path, err: Path
) -> None:
    """The child: the caller's environment and directory, its output into files, then `main`."""
    from hilrig.cli import main
    from hilrig.session.warm import enter_namespace

    os.environ.clear()
    os.environ.update(env)
    os.chdir(cwd)
    enter_namespace(namespace_file)
    for stream, path in ((sys.stdout, out), (sys.stderr, err)):
        stream.flush()
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        os.dup2(fd, stream.fileno())
        os.close(fd)
    sys.argv = ["hilrig", *argv]
    code = main(argv)
    sys.stdout.flush()
    sys.stderr.flush()
    sys.exit(code)


__all__ = ["CLI_PRELOAD", "run"]
