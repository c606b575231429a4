"""Files written whole: a temporary file beside the target, renamed over it only when the
writing ended without an error (a reader, or a later run, never sees half a file; an error or
Ctrl-C leaves the old file, or none, and no temporary behind).

    with replacing(Path("out/report.json")) as temporary:
        temporary.write_text(text)
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path


@contextlib.contextmanager
def replacing(path: Path) -> Iterator[Path]:
    """A temporary file beside `path` (its folder made if missing) that replaces `path` when the
    block ends without an error, readable by all as a file written with open() would be."""
    path.parent.mkdir(parents=True, exist_ok=True)
    descriptor, temporary = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    os.close(descriptor)
    try:
        yield Path(temporary)
        os.chmod(temporary, 0o644)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
