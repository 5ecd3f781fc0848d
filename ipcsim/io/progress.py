"""What ``ipcsim run`` shows while it works.

On a terminal: one live bar (rich) with the step, simulated time, Newton iterations of
the last step, active contacts and the time left. Otherwise (a log file, a pipe, CI):
a plain line every 5 % of the steps or every 30 s, whichever comes first, so a log shows
progress without a line per step. ``quiet``: nothing.
"""

from __future__ import annotations

import math
import sys
import time

LINE_FRACTION = 0.05  # plain mode: a line per 5 % of the run ...
LINE_SECONDS = 30.0  # ... or per 30 s of wall time
MODES = ("bar", "lines", "off")


def _clock(seconds: float) -> str:
    seconds = int(round(seconds))
    h, rest = divmod(seconds, 3600)
    m, s = divmod(rest, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


class RunProgress:
    """``update(step, time, newton, contacts)`` after every completed step. The time left
    follows the simulated time (from ``first_time`` to ``end_time``, s; by default the
    steps: with adaptive steps their pace is not the clock's) and leaves out the time
    spent compiling kernels (``compiled()``: seconds so far), which a first run after
    installing pays once."""

    def __init__(self, first_step: int, total_steps: int, mode: str, stream=None,
                 compiled=lambda: 0.0, first_time: float | None = None,
                 end_time: float | None = None):
        self.first, self.total, self.mode = first_step, total_steps, mode
        # the clock the time left follows: simulated time where given, else steps
        self.by_time = first_time is not None and end_time is not None
        self.first_time, self.end_time = ((first_time, end_time) if self.by_time
                                          else (first_step, total_steps))
        self.now = self.first_time
        self.stream = stream or sys.stdout
        self.compiled = compiled
        self.started = self.last_line = time.perf_counter()
        self.next_line_step = first_step
        self._bar = None
        if mode == "bar":
            from rich.console import Console
            from rich.progress import BarColumn, Progress, TextColumn

            self._bar = Progress(
                TextColumn("step {task.completed}/{task.total}"),
                BarColumn(),
                TextColumn("t={task.fields[t]}  newton={task.fields[newton]}  "
                           "contacts={task.fields[contacts]}  ETA {task.fields[eta]}"),
                console=Console(file=self.stream), transient=False)
            self._task = self._bar.add_task("run", total=total_steps, completed=first_step,
                                            t="-", newton="-", contacts="-", eta="-")
            self._bar.start()

    @staticmethod
    def mode_for(quiet: bool, stream=None) -> str:
        if quiet:
            return "off"
        stream = stream or sys.stdout
        return "bar" if getattr(stream, "isatty", lambda: False)() else "lines"

    def eta(self, step: int) -> float:
        """Seconds left at the pace of the simulated time so far (of the steps where no
        time was given), compiling left out."""
        now = self.now if self.by_time else step
        done = now - self.first_time
        if step <= self.first or not done > 0:
            return float("nan")
        stepping = max(0.0, time.perf_counter() - self.started - self.compiled())
        return stepping / done * (self.end_time - now)

    def update(self, step: int, t: float, newton: int, contacts: int) -> None:
        self.now = t
        if self.mode == "bar":
            left = self.eta(step)
            self._bar.update(self._task, completed=step, t=f"{t:.4g}s", newton=newton,
                             contacts=contacts, eta=_clock(left) if left == left else "-")
        elif self.mode == "lines":
            now = time.perf_counter()
            if step < self.total and step < self.next_line_step and now - self.last_line < LINE_SECONDS:
                return
            self.last_line = now
            self.next_line_step = step + max(1, math.ceil(LINE_FRACTION * self.total))
            print(f"step {step}/{self.total}  t={t:.4g}s  newton={newton}  "
                  f"contacts={contacts}  wall={_clock(now - self.started)}  "
                  f"ETA={_clock(self.eta(step)) if step > self.first else '-'}",
                  file=self.stream, flush=True)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.stop()
            self._bar = None
