"""The run report, ``OUT.json`` (DESIGN §7)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np


def _plain(value):
    """JSON-serialisable copy: arrays to lists, NumPy scalars to Python, non-finite to None."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


def write_report(path: str | Path, report: dict) -> None:
    """Write ``report`` as indented JSON, atomically."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.partial")
    tmp.write_text(json.dumps(_plain(report), indent=2) + "\n")
    os.replace(tmp, path)
