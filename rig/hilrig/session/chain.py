"""A modular robot fresh from the box: n firmware processes on one bus, none with a node id yet
(`--node-id 0xFF`: LSS only), each with its own serial number and non-volatile files, wired as
a chain by the enable line `hilrig.wire.lss` describes.

The rig emulates the wire: one file per link, `chain-<k>.on`, which exists while module k
drives its enable output high (it has a node id). Module k's `--chain-out` is module k + 1's
`--chain-in`; module 1 has no input (the master's line, always high).

    with UnconfiguredChain(private_bus, out_dir, serials=(0x31, 0x12, 0x24)) as chain:
        ... hilrig.wire.lss.LssCommissioner(network).number_chain(...)   # ids 1, 2, 3 in chain order
        chain.modules[0].firmware.restart()                             # power-cycle module 1
"""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Self

from boardproto.cia305 import NODE_ID_UNCONFIGURED
from hilrig.errors import FirmwareError
from hilrig.session.firmware import DEFAULT_EXECUTABLE, Firmware, Launcher


@dataclass(frozen=True)
class ChainModule:
    """One module: its place in the chain (1 = next to the master), serial number, firmware and
    the files that are its non-volatile memory."""

    position: int
    serial_number: int
    firmware: Firmware
    lss_store: Path
    params_file: Path


STARTED_LINE = "joint-firmware: node "
"""The firmware's start-up line, printed once its socket is open and the node started."""
READY_POLL_S = 0.05


def wait_until_listening(firmware: Firmware, timeout_s: float) -> None:
    """Return once the firmware printed its start-up line: a node without an id sends no
    boot-up, so its log is the only sign that it listens. FirmwareError if it died; the bound
    is a hang guard."""
    deadline = time.monotonic() + timeout_s
    while STARTED_LINE not in firmware.log_path.read_text(errors="replace"):
        firmware.check()
        if time.monotonic() >= deadline:
            raise FirmwareError(f"{firmware.log_path}: no start-up line within {timeout_s:g} s")
        threading.Event().wait(READY_POLL_S)


def chain_link(out_dir: Path, position: int) -> Path:
    """The emulated enable wire from module `position` to the next one."""
    return out_dir / f"chain-{position}.on"


class UnconfiguredChain:
    """Starts one firmware process per serial number, in chain order, and stops them all (a
    context manager). Stored node ids survive `firmware.restart()`: the files stay."""

    def __init__(
        self,
        launcher: Launcher,
        out_dir: Path,
        serials: Sequence[int],
        *,
        executable: Path = DEFAULT_EXECUTABLE,
        period_us: int | None = None,
        ready_timeout_s: float = 60.0,
    ) -> None:
        if len(set(serials)) != len(serials):
            raise ValueError(f"every module needs its own serial number, got {list(serials)}")
        self.out_dir = out_dir
        self.ready_timeout_s = ready_timeout_s
        self.modules: list[ChainModule] = []
        for position, serial in enumerate(serials, start=1):
            lss_store = out_dir / f"lss-{position}.bin"
            params_file = out_dir / f"params-module-{position}.bin"
            extra = ["--serial", str(serial), "--lss-store", str(lss_store)]
            extra += ["--chain-out", str(chain_link(out_dir, position))]
            if position > 1:
                extra += ["--chain-in", str(chain_link(out_dir, position - 1))]
            firmware = Firmware(
                launcher,
                node_id=NODE_ID_UNCONFIGURED,
                log_path=out_dir / f"firmware-module-{position}.log",
                period_us=period_us,
                params_file=params_file,
                extra_args=extra,
                executable=executable,
            )
            self.modules.append(ChainModule(position, serial, firmware, lss_store, params_file))
        self._stack = ExitStack()

    def __enter__(self) -> Self:
        self.out_dir.mkdir(parents=True, exist_ok=True)
        for module in self.modules:  # a fresh box: no id stored, every enable line low
            for path in (module.lss_store, module.params_file, chain_link(self.out_dir, module.position)):
                path.unlink(missing_ok=True)
        with ExitStack() as stack:
            for module in self.modules:
                stack.enter_context(module.firmware)
            for module in self.modules:
                wait_until_listening(module.firmware, self.ready_timeout_s)
            self._stack = stack.pop_all()
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, traceback: TracebackType | None
    ) -> None:
        self._stack.close()
