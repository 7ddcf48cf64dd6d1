"""The terminal's progress bar, an observer of the solve (tqdm on stderr)."""

from __future__ import annotations

import math
import sys

from daskrad.solve import Solution


def say(message: str, enabled: bool) -> None:
    """One line on stderr, ``daskrad: <message>``, naming the long step that starts now (the
    direct pass, the render: tens of seconds in a furnished room, before and after the bar).
    Only where the bar would show (``enabled`` and a terminal)."""
    if enabled and sys.stderr.isatty():
        print(f"daskrad: {message}", file=sys.stderr, flush=True)


class Bar:
    """Progress: shots done and the relative unshot RMS against the tolerance.

    The bar counts decades of unshot RMS reduction, ``0 → log10(1/tolerance)``. Disabled, it
    does nothing (``--quiet``, tests, and a stderr that is not a terminal: a log file would
    fill with carriage-return updates).
    """

    def __init__(self, tolerance: float, enabled: bool):
        self.bar = None
        if enabled and sys.stderr.isatty():
            from tqdm import tqdm

            self.total = max(1e-9, math.log10(1.0 / tolerance))
            self.bar = tqdm(total=round(self.total, 2), desc="", unit="dec",
                            bar_format="shooting: {percentage:3.0f}%|{bar}| {desc}",
                            file=sys.stderr)

    def __call__(self, sol: Solution) -> None:
        if self.bar is None or not sol.history:
            return
        it, rms, sec = sol.history[-1]
        done = min(self.total, math.log10(1.0 / max(rms, 1e-300)))
        self.bar.n = round(max(0.0, done), 2)
        self.bar.set_description_str(f"shot {it}, unshot {rms:.2e}, {sec:.1f}s", refresh=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
