"""The ``/daskrad`` dashboard page: the phase with a progress bar, iteration, unshot RMS curve
and a preview image.

The scheduler loads this module through ``distributed.scheduler.http.routes`` (the LocalCluster
of ``--workers N`` adds it; for a cluster of your own see ``cluster/README.md``). The client
publishes with ``client.set_metadata(["daskrad", key], value)`` (:class:`Watch`); the page
reads the scheduler's ``task_metadata`` and renders it, refreshing itself every two seconds. The
phase (``preprocessing``, ``direct light``, ``shooting``, ``rendering``) is published from the
moment the executor starts (:meth:`DaskExecutor.phase`), so the page is never blank.
``/daskrad/json`` serves the same data as JSON.
"""

from __future__ import annotations

import html
import json
import math

from distributed.http.utils import RequestHandler

REFRESH_SECONDS = 2


def _metadata(server) -> dict:
    meta = getattr(server, "task_metadata", {}) or {}
    return dict(meta.get("daskrad", {}))


def _curve_svg(history: list, tolerance: float, width: int = 480, height: int = 200) -> str:
    """log10 of the relative unshot RMS against shots, from 1 down to the tolerance."""
    if not history:
        return "<p>no batch applied yet</p>"
    bottom = math.log10(tolerance) if tolerance > 0 else -6.0
    last = max(h[0] for h in history) or 1
    pts = []
    for it, rms, _ in history:
        y = min(0.0, max(bottom, math.log10(max(rms, 1e-300))))
        pts.append(f"{40 + (width - 50) * it / last:.1f},{10 + (height - 30) * y / bottom:.1f}")
    tol_y = 10 + (height - 30)
    return (f'<svg width="{width}" height="{height}" style="background:#fff;border:1px solid #ccc">'
            f'<line x1="40" y1="{tol_y}" x2="{width - 10}" y2="{tol_y}" stroke="#c33" '
            'stroke-dasharray="4"/>'
            f'<text x="2" y="14" font-size="11">1</text>'
            f'<text x="2" y="{tol_y + 4}" font-size="11">{tolerance:.0e}</text>'
            f'<text x="{width - 90}" y="{height - 4}" font-size="11">shots: {last}</text>'
            f'<polyline fill="none" stroke="#236" stroke-width="1.5" '
            f'points="{" ".join(pts)}"/></svg>')


def phase_html(phase: dict) -> str:
    """The current phase (preprocessing, direct light, shooting, rendering) and a progress bar."""
    if not phase:
        return "<p>no run has started yet</p>"
    f = min(1.0, max(0.0, float(phase.get("fraction", 0.0))))
    detail = html.escape(str(phase.get("detail", "")))
    return (f"<h3>phase: {html.escape(str(phase.get('phase', '?')))}</h3>"
            f'<progress value="{f:.4f}" max="1" style="width:480px"></progress> '
            f"{100 * f:.0f} %" + (f" &middot; {detail}" if detail else ""))


class DaskradPage(RequestHandler):
    def get(self):
        m = _metadata(self.server)
        p = m.get("progress", {})
        rows = "".join(f"<tr><th align=left>{html.escape(str(k))}</th>"
                       f"<td>{html.escape(str(v))}</td></tr>"
                       for k, v in p.items() if k != "history")
        preview = m.get("preview")
        img = (f'<img src="data:image/png;base64,{preview}" width="256" '
               'style="image-rendering:pixelated">' if preview else "<p>no preview yet</p>")
        self.set_header("Content-Type", "text/html; charset=utf-8")
        self.write(
            "<!doctype html><html><head><title>daskrad</title>"
            f'<meta http-equiv="refresh" content="{REFRESH_SECONDS}"></head>'
            '<body style="font-family:sans-serif"><h2>daskrad: progressive refinement</h2>'
            + phase_html(m.get("phase", {}))
            + (f"<table>{rows}</table>" if p else "<p>no run has published progress yet</p>")
            + "<h3>relative unshot RMS (log scale)</h3>"
            + _curve_svg(p.get("history", []), float(p.get("tolerance", 1e-3)))
            + "<h3>preview</h3>" + img + "</body></html>")


class DaskradJSON(RequestHandler):
    def get(self):
        self.set_header("Content-Type", "application/json")
        self.write(json.dumps(_metadata(self.server)))


routes: list[tuple] = [
    (r"daskrad", DaskradPage, {}),
    (r"daskrad/json", DaskradJSON, {}),
]
