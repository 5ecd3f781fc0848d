"""Wall time per phase of a time step, as steps.csv reports it."""

from __future__ import annotations

import time
from collections import defaultdict


class PhaseTimer:
    """Accumulates wall time per phase: ``with timer("solve"): ...``."""

    def __init__(self):
        self.totals = defaultdict(float)

    def __call__(self, phase: str):
        return _Phase(self.totals, phase)

    def reset(self) -> dict[str, float]:
        out = dict(self.totals)
        self.totals.clear()
        return out


class _Phase:
    __slots__ = ("totals", "phase", "start")

    def __init__(self, totals, phase):
        self.totals, self.phase = totals, phase

    def __enter__(self):
        self.start = time.perf_counter()

    def __exit__(self, *exc):
        self.totals[self.phase] += time.perf_counter() - self.start
