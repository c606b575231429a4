"""python-can imports asammdf, and with it pandas, the moment `import can` runs, whenever asammdf
is installed (`can.io.mf4` tries it at import): about a second of every process's start-up on a
quick host, several in the bus stage's VM, for a format most runs never touch. Installed by
`hilrig`'s own import, this finder reports asammdf missing to python-can's MF4 module while that
module is first imported; `enable()`, called when a .mf4 file is actually read or written
(hilrig.session.logformats), imports it for real and runs the MF4 module again, so its reader and
writer (the same classes python-can's Logger and LogReader hold) find it. Anyone else importing
asammdf is never refused.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
from collections.abc import Sequence
from types import ModuleType

MF4_MODULE = "can.io.mf4"
_enabled = False


class _DeferAsammdf(importlib.abc.MetaPathFinder):
    def find_spec(
        self, fullname: str, path: Sequence[str] | None, target: ModuleType | None = None
    ) -> importlib.machinery.ModuleSpec | None:
        if _enabled or fullname.partition(".")[0] != "asammdf":
            return None
        frame = sys._getframe(1)
        while frame is not None:
            if frame.f_globals.get("__name__") == MF4_MODULE:
                raise ModuleNotFoundError(
                    "asammdf: deferred by hilrig until a .mf4 file is used", name=fullname
                )
            frame = frame.f_back
        return None


def install() -> None:
    """Defer python-can's import of asammdf (nothing to do once python-can's MF4 module is in)."""
    if MF4_MODULE not in sys.modules and not any(isinstance(f, _DeferAsammdf) for f in sys.meta_path):
        sys.meta_path.insert(0, _DeferAsammdf())


def enable() -> None:
    """asammdf for python-can's MF4 reader and writer from now on; ImportError if not installed."""
    global _enabled
    _enabled = True
    import asammdf  # noqa: F401  (ImportError: not installed)

    module = sys.modules.get(MF4_MODULE)
    if module is not None and getattr(module, "asammdf", None) is None:
        importlib.reload(module)  # in place: the classes python-can already holds see asammdf


__all__ = ["MF4_MODULE", "enable", "install"]
