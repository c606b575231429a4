"""Bus logs: written whole through python-can's loggers, and the master side of a log.

`whole_file_logger` is the one way the project writes a log (`hilrig record`, `hilrig sim`,
every scenario's bus.log): a `can.Logger` (format by extension: .log candump, .blf Vector,
.asc, .csv, .trc) writing to a hidden partial file that is renamed to the real name only once
the logger was stopped (flushed and closed; a BLF file gets its header and object count only
then). So the named file is always a whole log, also after Ctrl-C or SIGTERM; a hard kill
(SIGKILL) leaves it untouched and the partial file behind.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

from hilrig.table import RigTable

if TYPE_CHECKING:
    import can
    import cantools.database

LOG_FORMATS = (".log", ".blf", ".asc", ".csv", ".trc")


def partial_path(path: Path) -> Path:
    """Hidden temporary name beside `path`, with the same extension (it picks the format)."""
    return path.with_name(f".{path.stem}.partial{path.suffix}")


@contextmanager
def whole_file_logger(path: Path) -> Iterator[can.Listener]:
    """A python-can `can.Logger` whose file appears at `path` only whole (see the module)."""
    import can

    path.parent.mkdir(parents=True, exist_ok=True)
    partial = partial_path(path)
    logger = can.Logger(str(partial))
    try:
        yield logger
    finally:
        logger.stop()  # flush and close: the file is complete from here on
        os.replace(partial, path)


class BusRecorder:
    """Everything on a bus into a whole log, from a socket of its own (so it sees every
    sender's frames alike), until `close()`. The recorder owns `bus` and shuts it down."""

    def __init__(self, bus: can.BusABC, path: Path) -> None:
        import can

        self.path = path
        self._bus = bus
        self._stack = contextlib.ExitStack()
        self._stack.callback(bus.shutdown)
        logger = self._stack.enter_context(whole_file_logger(path))
        self._notifier = can.Notifier(bus, [logger], timeout=0.05)
        self._stack.callback(self._notifier.stop)  # runs first: no frame after the logger stops

    def close(self) -> None:
        self._stack.close()


def node_cob_ids(table: RigTable, node_id: int) -> frozenset[int]:
    """COB-IDs node `node_id` itself sends on (CiA 301 predefined connection set and the
    table's TPDOs): EMCY, TPDOs, SDO answers, heartbeat and boot-up."""
    tpdos = {pdo.cob_id(node_id) for pdo in table.board.tpdos}
    fixed = {0x080 + node_id, 0x580 + node_id, 0x700 + node_id}
    fixed |= {base + node_id for base in (0x180, 0x280, 0x380, 0x480)}
    return frozenset(tpdos | fixed)


def master_side(messages: Iterator[can.Message], table: RigTable, node_id: int) -> Iterator[can.Message]:
    """The frames of a log that node `node_id` did not send itself: what the master (and any
    other sender, e.g. an injected flood) put on the bus. Replayed into a fresh node, they drive
    it through the same run."""
    own = node_cob_ids(table, node_id)
    for message in messages:
        if message.is_extended_id or message.arbitration_id not in own:
            yield message


class NodeDbc:
    """The generated DBC read for node `node_id`: the DBC holds the default node's COB-IDs,
    a board at another node id sends the same messages shifted by the difference."""

    def __init__(self, database: cantools.database.can.Database, table: RigTable, node_id: int) -> None:
        self.database = database
        self._offset = node_id - table.board.node.default_node_id

    def message(self, cob_id: int) -> cantools.database.can.Message | None:
        """The DBC message a frame on `cob_id` carries, or None (not a PDO of this node)."""
        try:
            return self.database.get_message_by_frame_id(cob_id - self._offset)
        except KeyError:
            return None


__all__ = [
    "LOG_FORMATS",
    "BusRecorder",
    "NodeDbc",
    "master_side",
    "node_cob_ids",
    "partial_path",
    "whole_file_logger",
]
