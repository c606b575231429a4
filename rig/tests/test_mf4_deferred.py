"""hilrig.mf4_deferred: importing python-can after hilrig loads no asammdf (nor pandas); the first
.mf4 file read or written brings it in, and whoever imports asammdf themselves gets it."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path


def _run(code: str) -> str:
    done = subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, check=False
    )
    assert done.returncode == 0, done.stderr
    return done.stdout.strip()


def test_python_can_after_hilrig_loads_no_asammdf() -> None:
    out = _run(
        """
        import sys
        import hilrig, can
        print("asammdf" in sys.modules, "pandas" in sys.modules)
        """
    )
    assert out == "False False"


def test_the_first_mf4_file_brings_asammdf_in(tmp_path: Path) -> None:
    out = _run(
        f"""
        import sys
        import can
        from hilrig.session.logformats import open_reader, open_writer
        writer = open_writer(__import__("pathlib").Path({str(tmp_path / "bus.mf4")!r}))
        writer.on_message_received(can.Message(timestamp=1.0, arbitration_id=0x123, data=b"\\x01"))
        writer.stop()
        reader = open_reader(__import__("pathlib").Path({str(tmp_path / "bus.mf4")!r}))
        print("asammdf" in sys.modules, [bytes(m.data) for m in reader])
        """
    )
    assert out == "True [b'\\x01']"


def test_asammdf_imported_directly_is_never_refused() -> None:
    assert _run("import hilrig, can, asammdf; print(asammdf.__name__)") == "asammdf"
