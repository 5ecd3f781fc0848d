"""The penalty contact terms of the stability baseline: value, gradient and Hessian agree
with finite differences, the Hessian is PSD, and there is no feasibility filter."""

from __future__ import annotations

import numpy as np
import pytest

from ipcsim.contact.collision_mesh import CollisionMesh
from ipcsim.contact.collisions import build_collisions
from ipcsim.contact.planes import Planes
from ipcsim.kernels.contact import penalty as kp
from ipcsim.model.build import build_model
from ipcsim.model.generate import box_tet_mesh, write_msh
from ipcsim.potentials.base import StepContext, Triplets
from ipcsim.potentials.penalty_contact import PenaltyMeshContact, PenaltyPlaneContact
from ipcsim.scene import load_scene

DHAT = 0.05


def _fd_gradient(f, x, h=1e-7):
    g = np.zeros(x.size)
    for i in range(x.size):
        e = np.zeros(x.size)
        e[i] = h
        g[i] = (f((x.reshape(-1) + e).reshape(x.shape))
                - f((x.reshape(-1) - e).reshape(x.shape))) / (2 * h)
    return g


def _fd_hessian(grad, x, h=1e-7):
    cols = []
    for i in range(x.size):
        e = np.zeros(x.size)
        e[i] = h
        cols.append((grad((x.reshape(-1) + e).reshape(x.shape))
                     - grad((x.reshape(-1) - e).reshape(x.shape))) / (2 * h))
    return np.array(cols).T


def _dense(term, x):
    return term.hessian(x).tocsr(x.size).toarray()


class _AtPositions:
    """A mesh term with the collision set rebuilt at whatever x it is given (what the
    solver does at each Newton iterate), as a function of x alone."""

    def __init__(self, term, model):
        self.term, self.mesh = term, CollisionMesh.from_model(model)

    def ctx(self, x):
        return StepContext(collisions=build_collisions(self.mesh, x, DHAT))

    def value(self, x):
        return self.term.value(x, self.ctx(x))

    def gradient(self, x):
        return self.term.gradient(x, self.ctx(x))

    def hessian(self, x):
        return self.term.hessian(x, self.ctx(x))


@pytest.fixture(scope="module")
def two_cubes(tmp_path_factory):
    """Two generated cubes, the upper one turned and lowered into the lower one's d̂
    band (corners and edges over faces: point–triangle and edge–edge pairs)."""
    folder = tmp_path_factory.mktemp("penalty")
    write_msh(folder / "cube.msh", *box_tet_mesh(2, 2, 2, size=(1, 1, 1)))
    scene = folder / "scene.txt"
    scene.write_text("shapes input 2\n"
                     "cube.msh 0 0 0  0 0 0  1 1 1\n"
                     "cube.msh 0.13 1.03 0.07  17 11 23  1 1 1\n"
                     f"dHatAbs {0.3}\nturnOffGravity\n")
    model = build_model(load_scene(scene))
    x = np.array(model.initial_positions)
    top = model.vertex_shape == 1
    x[top, 1] -= x[top, 1].min() - 1.0 - 0.4 * DHAT  # lowest corner 0.4 d̂ above the face
    return model, x


def test_plane_penalty_matches_finite_differences():
    rng = np.random.default_rng(1)
    x = rng.uniform(-1, 1, (6, 3))
    x[:, 1] = np.array([-0.02, 0.01, 0.03, 0.049, 0.2, 0.0])  # below, inside band, above
    planes = Planes(np.arange(6), [[0.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]], [0.0])
    term = PenaltyPlaneContact(planes, DHAT, 1e3)
    gaps = np.maximum(0.0, DHAT - x[:, 1])
    assert term.value(x) == pytest.approx(0.5 * 1e3 * np.sum(gaps ** 2))
    np.testing.assert_allclose(term.gradient(x), _fd_gradient(term.value, x), atol=1e-6)
    np.testing.assert_allclose(_dense(term, x), _fd_hessian(term.gradient, x), atol=1e-4)
    assert np.isfinite(term.value(x))  # below the plane: a finite, growing energy
    assert term.max_step(x, -np.ones(x.size)) == 1.0  # no CCD


def test_mesh_penalty_matches_finite_differences(two_cubes):
    model, x = two_cubes
    term = _AtPositions(PenaltyMeshContact(DHAT, 1e2), model)
    c = term.ctx(x).collisions
    pt, ee = c.pt, c.ee
    assert len(pt) and len(ee)
    value = term.value(x)
    assert value > 0.0
    g = term.gradient(x)
    np.testing.assert_allclose(g, _fd_gradient(term.value, x), rtol=1e-5, atol=1e-5)
    # the exact (unprojected) Hessian against differences of the gradient
    H = Triplets(*kp.mesh_penalty_hessian(x, pt, ee, DHAT, 1e2, False)).tocsr(x.size).toarray()
    H_fd = _fd_hessian(term.gradient, x)
    np.testing.assert_allclose(H, H_fd, rtol=1e-4, atol=1e-5 * np.abs(H_fd).max())


def test_mesh_penalty_hessian_is_psd_and_pushes_through(two_cubes):
    model, x = two_cubes
    term = _AtPositions(PenaltyMeshContact(DHAT, 1e2), model)
    H = _dense(term, x)
    assert np.linalg.eigvalsh(0.5 * (H + H.T)).min() > -1e-8 * np.abs(H).max()
    # unsigned distance: a vertex just below the face is pushed further down, not back
    top = np.flatnonzero(model.vertex_shape == 1)
    corner = top[np.argmin(x[top, 1])]
    y = x.copy()
    y[model.vertex_shape == 1, 1] -= 0.4 * DHAT + 0.1 * DHAT  # corner now 0.1 d̂ inside
    assert term.gradient(y)[3 * corner + 1] > 0.0  # −∇P points down: deeper
    assert term.term.max_step(x, (y - x).reshape(-1) * 10) == 1.0
