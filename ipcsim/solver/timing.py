"""Wall time per phase of a time step, as steps.csv reports it."""

from __future__ import annotations

import time
from collections import defaultdict


class PhaseTimer:
    """Accumulates wall time per phase: ``with timer("solve"): ...``."""

    def __init__(self):
        self.totals = defaultdict(float)
        self._phases: dict[str, _Phase] = {}  # reused: a run enters them thousands of times

    def __call__(self, phase: str):
        timed = self._phases.get(phase)
        if timed is None or timed.start is not None:  # new, or entered again within itself
            timed = _Phase(self.totals, phase)
            self._phases.setdefault(phase, timed)
        return timed

    def reset(self) -> dict[str, float]:
        out = dict(self.totals)
        self.totals.clear()
        return out


class _Phase:
    __slots__ = ("totals", "phase", "start")

    def __init__(self, totals, phase):
        self.totals, self.phase, self.start = totals, phase, None

    def __enter__(self):
        self.start = time.perf_counter()

    def __exit__(self, *exc):
        self.totals[self.phase] += time.perf_counter() - self.start
        self.start = None
