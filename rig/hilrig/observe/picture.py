"""A picture with every failure: a failed scenario check (`hilrig.expect.FailedCheck`) drawn as a
PNG a reviewer can glance at in CI's artifacts, no viewer needed: the field over simulation
time, the band it was expected in, and the moment it failed.

    expect = Expect(rig, evidence=..., picture=FailurePictures(Path("out/scenarios/x/pictures")))

Drawn with matplotlib's Agg backend (no display; without matplotlib the failure says what to
install, `PictureUnavailable`, and keeps its text); written whole (a temporary file renamed). The
colours are fixed (`CURVE`, `BAND`, `FAILED_AT`) so a check without a browser can find each part
in the image (`rig/tests/test_failure_picture.py`).
"""

from __future__ import annotations

import re
import textwrap
from dataclasses import dataclass, field
from pathlib import Path

from hilrig.expect import FailedCheck, PictureUnavailable
from hilrig.files import replacing

CURVE = "#1f3fbf"
"""The field's samples."""
BAND = "#2ca02c"
"""The values it was expected in (filled lighter, edged in this colour)."""
BAND_ALPHA = 0.25
FAILED_AT = "#d62728"
"""The moment the check failed: a vertical line and a marker on the sample."""
SIZE_IN = (9.0, 4.5)
DPI = 100
EXTRA = "hilrig[pytest]"
"""The install that brings matplotlib, with pytest (rig/pyproject.toml's extra)."""
MAX_PICTURES = 20
"""Per `FailurePictures`: a scenario that fails in a loop does not fill the disk."""


@dataclass
class FailurePictures:
    """Draws each failed check into `folder` as <field>-<check>[-n].png; returns its path."""

    folder: Path
    drawn: list[Path] = field(default_factory=list)

    def __call__(self, failed: FailedCheck) -> Path | None:
        if len(self.drawn) >= MAX_PICTURES:
            return None
        stem = re.sub(r"[^A-Za-z0-9_.-]+", "_", f"{failed.name}-{failed.check}")
        path = self.folder / f"{stem}.png"
        number = 1
        while path in self.drawn or path.exists():
            number += 1
            path = self.folder / f"{stem}-{number}.png"
        draw(failed, path)
        self.drawn.append(path)
        return path


def draw(failed: FailedCheck, path: Path) -> Path:
    """The PNG of one failed check at `path` (parent folders made); PictureUnavailable without
    matplotlib."""
    try:
        import matplotlib
    except ImportError:
        raise PictureUnavailable(f"no picture: matplotlib is not installed (pip install '{EXTRA}')") from None

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    figure = Figure(figsize=SIZE_IN, dpi=DPI)
    axes = figure.add_subplot()
    t, v = failed.t, failed.v
    axes.plot(t, v, color=CURVE, linewidth=1.5, label=failed.name)
    if failed.band is not None and t.size:
        low, high = failed.band
        start = max(failed.band_from_s, float(t[0]))
        end = float(t[-1])
        axes.fill_between([start, end], low, high, color=BAND, alpha=BAND_ALPHA, linewidth=0,
                          label=f"expected: {low:.4g} .. {high:.4g}")
        axes.hlines([low, high], start, end, colors=BAND, linewidth=1.0)
    if failed.at_s is not None:
        axes.axvline(failed.at_s, color=FAILED_AT, linewidth=2.0, label=f"failed at t = {failed.at_s:.3f} s")
        if t.size:
            i = min(int(abs(t - failed.at_s).argmin()), t.size - 1)
            axes.plot([t[i]], [v[i]], "o", color=FAILED_AT, markersize=6)
    axes.set_xlabel("simulation time [s]")
    axes.set_ylabel(failed.name)
    axes.grid(True, alpha=0.3)
    axes.legend(loc="best", fontsize=8)
    title = failed.message.split("; ")[0]
    axes.set_title("\n".join(textwrap.wrap(title, 100)), fontsize=9)
    figure.tight_layout()
    with replacing(path) as temporary:
        figure.savefig(temporary, format="png")
    return path


__all__ = ["BAND", "CURVE", "FAILED_AT", "FailurePictures", "draw"]
