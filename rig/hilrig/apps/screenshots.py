"""One picture per dashboard made for a trace (`make screenshots`, tools/screenshots.py): each
dashboard shown in the Rerun web viewer in headless Chromium on the trace it is made for
(`hilrig.observe.browser.check_dashboards`: the views as the dashboard lays them out, the
recording whole, the picture taken once it holds still), and the problems the viewer showed.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from hilrig.observe.browser import browser_missing, check_dashboards
from hilrig.observe.dashboard_check import fitting_dashboards
from hilrig.observe.reader import Trace

__all__ = ["browser_missing", "shoot"]


def shoot(trace: Path, out: Path, shots: Path) -> list[str]:
    """Every dashboard made for `trace`, each to out/<name>.png; the problems the viewer showed
    (a view with no data of its own, the demo's empty SDO abort log, is no problem here: the
    browser stage checks every series on a scenario trace made to fill them all)."""
    dashboards = fitting_dashboards(Trace.read(trace))
    problems: list[str] = []
    shown = check_dashboards(trace, list(dashboards), shots)
    for name, result in shown.items():
        problems += [f"{name}: {problem}" for problem in result.problems()]
        shutil.copyfile(result.screenshot, out / f"{name}.png")
        print(f"screenshots: {out / f'{name}.png'}", flush=True)
    return problems
