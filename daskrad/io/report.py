"""The run report, ``OUT.json`` (docs/design.md §7)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np


def plain(value, *, keep_nonfinite: bool = False):
    """JSON-serialisable copy: arrays to lists, NumPy scalars to Python, non-finite to None.

    Floats keep their value (a float64 round-trips exactly through JSON). With
    ``keep_nonfinite`` inf and nan stay floats, for callers that encode them themselves (the
    solution store's attributes and contexts, :mod:`daskrad.distributed.store`).
    """
    if isinstance(value, dict):
        return {str(k): plain(v, keep_nonfinite=keep_nonfinite) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v, keep_nonfinite=keep_nonfinite) for v in value]
    if isinstance(value, np.ndarray):
        return plain(value.tolist(), keep_nonfinite=keep_nonfinite)
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not keep_nonfinite and not np.isfinite(value):
        return None
    return value


def write_report(path: str | Path, report: dict) -> None:
    """Write ``report`` as indented JSON, atomically."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.partial")
    try:
        tmp.write_text(json.dumps(plain(report), indent=2) + "\n")
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)       # disk full: nothing half-written stays
        raise
