"""What a run says as it goes: on a terminal the solve's bar (tqdm on stderr) and a line as
each long step starts; on a stderr that is a file or a pipe (a batch job's log) a line now and
then (:class:`Heartbeat`). Observers only: nothing here changes what a run computes."""

from __future__ import annotations

import math
import sys
import threading
import time

from daskrad.solve import Solution

#: Seconds between two lines of a :class:`Heartbeat`: a run shorter than this says nothing in a
#: log, a furnished room's few minutes a line or two a step, a paper-scale run on a cluster
#: (hours) a few hundred lines.
HEARTBEAT_SECONDS = 30.0


class Heartbeat:
    """Progress where the bar cannot show: when ``enabled`` and stderr is not a terminal,
    a line every ``seconds`` (:data:`HEARTBEAT_SECONDS`), ``daskrad: 2:30 shooting: shot
    4,120, relative unshot RMS 3.1e-03 (tolerance 0.001)``: the time since the run began and
    the step now running (:meth:`say`, :meth:`shots`), from a thread of its own, since a step
    waits on its tasks for minutes. A log otherwise heard nothing between the start of a
    furnished room's run and its end. On a terminal it prints the step lines itself (the bar
    shows the solve); disabled (``-q``) it says nothing. :meth:`close` ends it before the run
    returns or raises, so a run's error line is its last (after the heartbeats of a long run
    that failed: a scene that took minutes to load and was then refused)."""

    def __init__(self, enabled: bool, seconds: float | None = None):
        self.enabled = enabled
        self.terminal = sys.stderr.isatty()
        self.status = "loading and meshing the scene"   # the step now running
        self.seconds = float(HEARTBEAT_SECONDS if seconds is None else seconds)
        self.beats = 0                  # lines written to the log so far
        self._end: str | None = None
        self._lock = threading.Lock()
        self._begun = time.monotonic()
        self._stop = threading.Event()
        self._thread = None
        if enabled and not self.terminal:
            self._thread = threading.Thread(target=self._beat, name="daskrad-heartbeat",
                                            daemon=True)
            self._thread.start()

    def say(self, message: str) -> None:
        """The step that starts now: one line ``daskrad: <message>`` on a terminal (the
        direct pass, the render: tens of seconds in a furnished room, before and after the
        bar); in a log the next heartbeat's status, and a line at once in a run long enough
        to have had a heartbeat (the log then shows when each later step began)."""
        self.status = message
        if self.enabled and self.terminal:
            print(f"daskrad: {message}", file=sys.stderr, flush=True)
        elif self._thread is not None and self.beats:
            self._line(message)

    def ended(self, summary: str) -> None:
        """How the run ended (``done: 967 shots, converged``), written at :meth:`close` to a
        log that had a heartbeat: its last line is then the run's end, not a step of it."""
        self._end = summary

    def shots(self, sol: Solution, tolerance: float) -> None:
        """The solve's progress after a batch, for the next heartbeat."""
        if sol.history:
            it, rms, _ = sol.history[-1]
            self.status = (f"shooting: shot {int(it):,}, relative unshot RMS {rms:.1e} "
                           f"(tolerance {tolerance:g})")

    def close(self) -> None:
        """No more lines (the run ended, or failed: its error is the last line), but the
        end (:meth:`ended`) of a run that had a heartbeat."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join()
            if self._end is not None and self.beats:
                self._line(self._end)

    def _beat(self) -> None:
        while not self._stop.wait(self.seconds):
            if not self._line(self.status):
                return

    def _line(self, text: str) -> bool:
        """``daskrad: M:SS text`` in one write (a warning from the run's thread never splits
        it); False when the log is gone (a closed pipe)."""
        minutes, secs = divmod(int(time.monotonic() - self._begun), 60)
        with self._lock:
            try:
                sys.stderr.write(f"daskrad: {minutes}:{secs:02d} {text}\n")
                sys.stderr.flush()
            except (OSError, ValueError):
                return False
            self.beats += 1
        return True


class Bar:
    """Progress: shots done and the relative unshot RMS against the tolerance.

    The bar counts decades of unshot RMS reduction, ``0 → log10(1/tolerance)``. Disabled, it
    does nothing (``--quiet``, tests, and a stderr that is not a terminal: a log file would
    fill with carriage-return updates; a :class:`Heartbeat` given hears every batch and speaks
    there).
    """

    def __init__(self, tolerance: float, enabled: bool, heartbeat: Heartbeat | None = None):
        self.bar = None
        self.tolerance = tolerance
        self.heartbeat = heartbeat
        if enabled and sys.stderr.isatty():
            from tqdm import tqdm

            self.total = max(1e-9, math.log10(1.0 / tolerance))
            self.bar = tqdm(total=round(self.total, 2), desc="", unit="dec",
                            bar_format="shooting: {percentage:3.0f}%|{bar}| {desc}",
                            file=sys.stderr)

    def __call__(self, sol: Solution) -> None:
        if self.heartbeat is not None:
            self.heartbeat.shots(sol, self.tolerance)
        if self.bar is None or not sol.history:
            return
        it, rms, sec = sol.history[-1]
        done = min(self.total, math.log10(1.0 / max(rms, 1e-300)))
        self.bar.n = round(max(0.0, done), 2)
        self.bar.set_description_str(f"shot {it}, unshot {rms:.2e}, {sec:.1f}s", refresh=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
