"""Rayleigh damping's matrix: D = (k/h)·∇²Ψ(xₙ), the elastic energy's own (projected)
Hessian at the step's start scaled by k/h alone, as the original's computeDampingMtr;
with dampingRatio r (k = ¾ r h³) that is ¾ r h²∇²Ψ whichever the integrator."""

from __future__ import annotations

import numpy as np
import pytest

from ipcsim.model.build import build_model
from ipcsim.model.generate import box_tet_mesh, write_msh
from ipcsim.potentials.base import StepContext
from ipcsim.scene import load_scene
from ipcsim.simulation import Simulation

H = 0.01
RATIO = 0.4


def _simulation(folder, integrator):
    points, tets = box_tet_mesh(2, 1, 1, size=(0.2, 0.1, 0.1))
    write_msh(folder / "bar.msh", points, tets)
    scene = folder / f"{integrator}.txt"
    scene.write_text(f"shapes input 1\nbar.msh 0 0.5 0  0 0 0  1 1 1\nselfCollisionOff\n"
                     f"time 1 {H}\ntimeIntegration {integrator}\ndampingRatio {RATIO}\n")
    return Simulation(build_model(load_scene(scene)))


@pytest.mark.parametrize("integrator", ["BE", "NM"])
def test_the_damping_matrix_is_k_over_h_times_the_unweighted_elastic_hessian(tmp_path,
                                                                             integrator):
    s = _simulation(tmp_path, integrator)
    rng = np.random.default_rng(5)
    x_n = s.state.x + rng.uniform(-0.005, 0.005, s.state.x.shape)  # a stressed start
    elastic = s.potential.term("elasticity").hessian(x_n)
    damping = s.potential.term("damping")
    ctx = StepContext(x_start=x_n, x_tilde=x_n, acceleration=np.zeros_like(x_n),
                      kinematic=np.zeros(len(x_n), bool), target=x_n, dhat=s.model.dhat,
                      damping=damping.lag(x_n, elastic))
    n = x_n.size
    K = elastic.tocsr(n).toarray()
    D = damping.hessian(x_n, ctx).tocsr(n).toarray()
    assert np.abs(K).max() > 0
    k = 0.75 * RATIO * H**3
    np.testing.assert_allclose(D, (k / H) * K, rtol=1e-12, atol=1e-12 * np.abs(K).max())
    # the gradient and value of ½ Δxᵀ D Δx at x = xₙ + Δx
    dx = rng.normal(size=n) * 1e-3
    x = x_n + dx.reshape(-1, 3)
    np.testing.assert_allclose(damping.gradient(x, ctx), D @ dx, rtol=1e-10,
                               atol=1e-14 * np.abs(D @ dx).max())
    assert damping.value(x, ctx) == pytest.approx(0.5 * dx @ D @ dx, rel=1e-10)


def test_newmark_and_backward_euler_damp_with_the_same_matrix(tmp_path):
    be, nm = (_simulation(tmp_path, i) for i in ("BE", "NM"))
    x_n = be.state.x * 1.01
    d_be = be.potential.term("damping").lag(x_n, be.potential.term("elasticity").hessian(x_n))
    d_nm = nm.potential.term("damping").lag(x_n, nm.potential.term("elasticity").hessian(x_n))
    n = x_n.size
    np.testing.assert_array_equal(d_be.triplets.tocsr(n).toarray(),
                                  d_nm.triplets.tocsr(n).toarray())
