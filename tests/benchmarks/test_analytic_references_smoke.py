"""Smoke run of the analytic references (a few steps per case): each measurement must be
as close to its exact value as those few steps allow. The bounds are far above what a
working solver gives (see docs/benchmarks.md) and far below what a broken one would."""

from __future__ import annotations

import csv

import pytest

from benchmarks.analytic_references import SMOKE, run


@pytest.fixture(scope="module")
def smoke(tmp_path_factory):
    out = tmp_path_factory.mktemp("analytic")
    return out, run(smoke=True, out=out)


def _one(smoke, case_prefix, quantity_start):
    found = [r for r in smoke[1]
             if r.case.startswith(case_prefix) and r.quantity.startswith(quantity_start)]
    assert len(found) == 1, (case_prefix, quantity_start)
    return found[0]


def test_free_fall_matches_each_integrators_solution(smoke):
    n = SMOKE["fall"]
    for integrator in ("BE", "NM"):
        discrete = _one(smoke, f"a. free fall, {integrator}", "drop (m) vs discrete")
        assert discrete.error < 1e-10 and discrete.steps == n
    # backward Euler drops h²g n(n+1)/2, i.e. (n+1)/n times ½ g t²; Newmark exactly ½ g t²
    be = _one(smoke, "a. free fall, BE", "drop (m) vs continuous")
    assert be.error == pytest.approx(1.0 / n, abs=1e-9)
    assert _one(smoke, "a. free fall, NM", "drop (m) vs continuous").error < 1e-10


def test_incline_slides_at_coulomb_rate_and_sticks_within_creep(smoke):
    slide = _one(smoke, "b. incline, μ = 0.3", "acceleration")
    assert slide.analytic == pytest.approx(9.80665 * (0.5 - 0.3) * 2 / 5 ** 0.5)
    assert slide.error < 0.01
    creep = _one(smoke, "b. incline, μ = 0.6", "creep speed")
    assert creep.error < 0.05 and 0 < creep.measured < creep.bound  # bound: ε_v
    held = _one(smoke, "b. incline, μ = 0.6", "slide in")
    assert abs(held.measured) < held.bound  # ε_v·t


@pytest.mark.parametrize("case", ["c. collision, frictionless", "c. collision, μ"])
def test_collisions_conserve_momentum(smoke, case):
    per_step = _one(smoke, case, "max ‖Δp‖ in one step")
    overall = _one(smoke, case, "‖p_end − p₀‖")
    assert per_step.error < 1e-10 and overall.error < 1e-10


def test_cube_rests_within_dhat_without_drift(smoke):
    mean = _one(smoke, "d. cube", "mean bottom gap")
    lowest = _one(smoke, "d. cube", "smallest gap")
    highest = _one(smoke, "d. cube", "largest bottom gap")
    drift = _one(smoke, "d. cube", "centre-of-mass drift")
    dhat = mean.bound
    assert 0.0 < lowest.measured <= highest.measured < 1.0  # every gap in (0, d̂)
    assert mean.error < 0.05  # the barrier carries the weight where it should
    assert drift.measured < 1e-2 * dhat


def test_vibration_energy_backward_euler_decays_newmark_conserves(smoke):
    ratio = _one(smoke, "e. vibration, BE", "energy ratio per step")
    assert ratio.error < 1e-4 and ratio.measured < 0.99  # a visible, exact decay
    lost = _one(smoke, "e. vibration, BE", "fraction of energy lost")
    assert lost.error < 1e-3
    assert _one(smoke, "e. vibration, NM", "largest energy change").error < 1e-3


def test_csv_and_chart_are_written(smoke):
    out, rows = smoke
    with open(out / "analytic_references.csv") as f:
        written = list(csv.DictReader(f))
    assert [(w["case"], w["quantity"]) for w in written] == [(r.case, r.quantity) for r in rows]
    for w, r in zip(written, rows):
        assert float(w["error"]) == pytest.approx(r.error, rel=1e-9, abs=1e-300)
    png = out / "energy_oscillation.png"
    assert png.stat().st_size > 1000 and png.read_bytes()[:4] == b"\x89PNG"
