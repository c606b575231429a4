"""tools/dist.py points the checkout's `boardproto` and `dashboards` imports under hilrig in the
staged sdist tree, and stops at a spelling it would leave pointing at a top-level name."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

_SPEC = importlib.util.spec_from_file_location("dist_tool", Path(__file__).resolve().parents[1] / "dist.py")
assert _SPEC is not None and _SPEC.loader is not None
_DIST = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(_DIST)
_repoint = _DIST._repoint


@pytest.mark.parametrize(
    ("source", "staged"),
    [
        ("from boardproto import load_table\n", "from hilrig.boardproto import load_table\n"),
        ("from boardproto.cia301 import (\n", "from hilrig.boardproto.cia301 import (\n"),
        ("    from dashboards.joint import x\n", "    from hilrig.dashboards.joint import x\n"),
        (
            "        import dashboards  # type: ignore[import-not-found]\n",
            "        from hilrig import dashboards  # type: ignore[import-not-found]\n",
        ),
        ("from boardprotocol import x\n", "from boardprotocol import x\n"),
        ('"""boardproto: the generators"""\n', '"""boardproto: the generators"""\n'),
    ],
)
def test_imports_are_pointed_under_hilrig(source: str, staged: str) -> None:
    assert _repoint(source) == staged


@pytest.mark.parametrize("source", ["import boardproto.cia301\n", "import dashboards as d\n"])
def test_a_spelling_it_cannot_point_stops_the_build(source: str) -> None:
    with pytest.raises(SystemExit, match="cannot point this import under hilrig"):
        _repoint(source)
