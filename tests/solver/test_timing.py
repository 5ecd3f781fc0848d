"""PhaseTimer: wall time per phase, with its context objects reused."""

import time

from ipcsim.solver.timing import PhaseTimer


def test_phases_accumulate_and_reset():
    timer = PhaseTimer()
    for _ in range(3):
        with timer("solve"):
            time.sleep(0.002)
    with timer("energy"):
        pass
    totals = timer.reset()
    assert set(totals) == {"solve", "energy"}
    assert totals["solve"] >= 0.006
    assert totals["energy"] < totals["solve"]
    assert timer.reset() == {}


def test_a_phase_entered_within_itself_counts_the_outer_span_once_and_the_inner_again():
    timer = PhaseTimer()
    start = time.perf_counter()
    with timer("energy"):
        time.sleep(0.002)
        with timer("energy"):
            time.sleep(0.004)
    outer = time.perf_counter() - start
    total = timer.reset()["energy"]
    # outer span (≥ 6 ms) plus the inner one (≥ 4 ms), never more than twice the outer
    assert 0.010 <= total <= 2 * outer


def test_a_phase_left_by_an_exception_can_be_entered_again():
    timer = PhaseTimer()
    try:
        with timer("solve"):
            raise ValueError
    except ValueError:
        pass
    with timer("solve"):
        time.sleep(0.002)
    assert timer.reset()["solve"] >= 0.002
