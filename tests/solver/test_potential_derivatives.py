"""Finite-difference checks of every term of the incremental potential as the simulation
assembles it (inertia, body force, elasticity, plane contact, damping) and of their sum,
on a small deformed body near a plane."""

from __future__ import annotations

import numpy as np
import pytest

from ipcsim.model.build import build_model
from ipcsim.model.generate import box_tet_mesh, write_msh
from ipcsim.potentials.base import StepContext, Triplets
from ipcsim.scene import load_scene
from ipcsim.simulation import Simulation


@pytest.fixture(scope="module", params=["NH", "FCR"])
def sim(request, tmp_path_factory):
    folder = tmp_path_factory.mktemp("fd")
    points, tets = box_tet_mesh(2, 1, 1, size=(0.2, 0.1, 0.1))
    write_msh(folder / "bar.msh", points, tets)
    scene = folder / "s.txt"
    scene.write_text(f"shapes input 1\nbar.msh 0 0.0005 0  0 0 0  1 1 1\nenergy {request.param}\n"
                     "selfCollisionOff\nground 0 0\ndampingStiff 0.3\ndHatAbs 0.002\n"
                     "kappa 1e4\n")
    s = Simulation(build_model(load_scene(scene)))
    rng = np.random.default_rng(3)
    x = s.state.x + rng.uniform(-0.01, 0.01, s.state.x.shape)
    x[:, 1] = np.maximum(x[:, 1], 2e-4)  # some vertices within d-hat of the ground
    x_n = s.state.x
    damping = s.potential.term("damping").lag(x_n, s.potential.term("elasticity").hessian(x_n))
    ctx = StepContext(x_start=x_n, x_tilde=x_n + 0.003,
                      acceleration=np.tile([0.0, -9.8, 1.0], (len(x), 1)),
                      kinematic=np.zeros(len(x), bool), target=x_n, dhat=s.model.dhat,
                      damping=damping)
    return s, x, ctx


def _term(s, name):
    return s.potential.term("plane contact" if name == "contact" else name.replace("_", " "))


def _fd_gradient(f, x, eps):
    g = np.zeros(x.size)
    flat = x.reshape(-1)
    for i in range(x.size):
        xp, xm = flat.copy(), flat.copy()
        xp[i] += eps
        xm[i] -= eps
        g[i] = (f(xp.reshape(-1, 3)) - f(xm.reshape(-1, 3))) / (2 * eps)
    return g


def _fd_hessian(grad, x, eps):
    H = np.zeros((x.size, x.size))
    flat = x.reshape(-1)
    for i in range(x.size):
        xp, xm = flat.copy(), flat.copy()
        xp[i] += eps
        xm[i] -= eps
        H[:, i] = (grad(xp.reshape(-1, 3)) - grad(xm.reshape(-1, 3))) / (2 * eps)
    return H


TERMS = ["inertia", "body_force", "elasticity", "contact", "damping"]


@pytest.mark.parametrize("name", TERMS)
def test_term_gradient_matches_finite_differences(sim, name):
    s, x, ctx = sim
    term = _term(s, name)
    g = term.gradient(x, ctx)
    fd = _fd_gradient(lambda y: term.value(y, ctx), x, 1e-7)
    assert np.abs(g).max() > 0
    np.testing.assert_allclose(g, fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())


@pytest.mark.parametrize("name", ["inertia", "damping", "contact"])
def test_exactly_convex_terms_have_the_finite_difference_hessian(sim, name):
    """These terms' Hessians are PSD already (contact: rank-one with a positive
    coefficient near the plane), so the projected Hessian equals the true one."""
    s, x, ctx = sim
    term = _term(s, name)
    H = term.hessian(x, ctx).tocsr(x.size).toarray()
    fd = _fd_hessian(lambda y: term.gradient(y, ctx), x, 1e-7)
    np.testing.assert_allclose(H, fd, rtol=1e-4, atol=1e-6 * np.abs(fd).max())


def test_incremental_potential_gradient_and_psd_hessian(sim):
    s, x, ctx = sim
    kappa = s.state.kappa
    data = s.potential.kernel.data(ctx)
    g = s.potential.evaluate(x, ctx, data, 1).gradient(kappa)
    fd = _fd_gradient(lambda y: s.potential.evaluate(y, ctx, data).energy(kappa), x, 1e-7)
    np.testing.assert_allclose(g, fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())
    static, dynamic = s.potential.hessian(x, ctx, data, kappa, dense=False)
    H = Triplets.concat(static + dynamic).tocsr(x.size).toarray()
    assert np.allclose(H, H.T)
    assert np.linalg.eigvalsh(H).min() > 0  # PSD local blocks + mass: positive definite


def test_the_potential_of_a_shorter_bdf2_step_matches_finite_differences(sim):
    """Weighted for a BDF2 step of 0.6 dt after one of dt (w = (βh)², the barrier by
    w / dt², damping's scale βh·k/dt², its displacement from x̂): gradient and PSD
    Hessian as the simulation assembles them."""
    from ipcsim.potentials.terms import for_step
    from ipcsim.solver.integrator import BDF2, StepHistory

    s, x, ctx = sim
    dt = s.model.dt
    x_n = ctx.x_start
    integrator = BDF2(0.6 * dt, StepHistory(x_n - 0.001, np.zeros_like(x_n), dt))
    potential = for_step(s.potential, s.model, integrator, s.integrator.force_weight)
    w = integrator.force_weight
    weights = {t.term.name: t.weight for t in potential.terms}
    assert weights["elasticity"] == weights["body force"] == w
    assert weights["plane contact"] == w / dt ** 2
    origin = integrator.lag_origin(x_n)
    damping = potential.term("damping").lag(origin, potential.term("elasticity").hessian(x_n))
    step_ctx = StepContext(x_start=x_n, slip_origin=origin, x_tilde=ctx.x_tilde,
                           acceleration=ctx.acceleration, kinematic=ctx.kinematic,
                           target=ctx.target, dhat=ctx.dhat, damping=damping)
    kappa = s.state.kappa
    data = potential.kernel.data(step_ctx)
    g = potential.evaluate(x, step_ctx, data, 1).gradient(kappa)
    fd = _fd_gradient(lambda y: potential.evaluate(y, step_ctx, data).energy(kappa), x, 1e-7)
    np.testing.assert_allclose(g, fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())
    static, dynamic = potential.hessian(x, step_ctx, data, kappa, dense=False)
    H = Triplets.concat(static + dynamic).tocsr(x.size).toarray()
    assert np.allclose(H, H.T) and np.linalg.eigvalsh(H).min() > 0
