"""A run's progress: a tqdm bar where someone watches, a line now and then in a log, or nothing."""
from __future__ import annotations

import sys
import time
from typing import TYPE_CHECKING

from .execute import shows_progress

if TYPE_CHECKING:
    from ..scene import Scene

# Seconds between two progress lines of a run that shows no bar (stderr no terminal: a log).
PROGRESS_LOG_EVERY = 30.0


def make_progress(scene: Scene, progress: bool | None, initial: int = 0):
    """The run's progress: a tqdm bar where one is shown (``execute.shows_progress``), one line now
    and then on stderr when progress is None and nobody watches (a log: ``LogProgress``), else nothing.
    Each has ``update(points)`` and ``close()``."""
    if shows_progress(progress):
        from tqdm.auto import tqdm

        return tqdm(total=scene.n_points, initial=initial, unit="pt", unit_scale=scene.n_points >= 100_000,
                    dynamic_ncols=True, desc=scene.name, smoothing=0.1)
    if progress is None:
        return LogProgress(scene.name, scene.n_points, initial)
    return NoProgress()


class NoProgress:
    def update(self, n: int) -> None:
        pass

    def close(self) -> None:
        pass


class LogProgress:
    """Progress for a log (stderr no terminal, e.g. a batch job): at most one line per
    PROGRESS_LOG_EVERY seconds, "mechsweep: NAME: 12,000 / 1,000,000 points, 1.2 %, ETA 3 min",
    and a last line with the run's time when any line was written (a short run writes none)."""

    def __init__(self, name: str, total: int, initial: int = 0):
        self.name, self.total, self.done, self.first = name, total, initial, initial
        self.t0 = self.last = time.monotonic()
        self.lines = 0

    def update(self, n: int) -> None:
        self.done += n
        now = time.monotonic()
        if now - self.last >= PROGRESS_LOG_EVERY and self.done < self.total:
            self.last = now
            rate = (self.done - self.first) / max(now - self.t0, 1e-9)
            eta = f", ETA {duration((self.total - self.done) / rate)}" if rate > 0 else ""
            self._print(f"{self.done:,} / {self.total:,} points, {100.0 * self.done / self.total:.1f} %{eta}")

    def close(self) -> None:
        if self.lines and self.done >= self.total:
            self._print(f"{self.done:,} / {self.total:,} points, 100 %, in {duration(time.monotonic() - self.t0)}")

    def _print(self, text: str) -> None:
        self.lines += 1
        print(f"mechsweep: {self.name}: {text}", file=sys.stderr, flush=True)


def duration(seconds: float) -> str:
    """A rough duration for a progress line: 40 s, 3 min, 2.5 h."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 90 * 60:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"
