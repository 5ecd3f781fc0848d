"""The one floating-point tet volume (kernels/algebra/linalg.py) and the places that use it."""

from __future__ import annotations

import numpy as np
import pytest

from ipcsim.kernels.contact import intersection as KI
from ipcsim.kernels.algebra import linalg as LA
from ipcsim.model.generate import box_tet_mesh
from ipcsim.model.surface import tet_signed_volumes as surface_volumes


def _random_tets(seed, n=60, m=200):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n, 3)) * 10.0 ** rng.uniform(-3, 3)
    tets = np.array([rng.choice(n, 4, replace=False) for _ in range(m)], dtype=np.int64)
    return x, tets


@pytest.mark.parametrize("seed", range(3))
def test_tet_signed_volumes_match_numpy(seed):
    x, tets = _random_tets(seed)
    got = LA.tet_signed_volumes(x, tets)
    Dm = np.stack([x[tets[:, c]] - x[tets[:, 0]] for c in (1, 2, 3)], axis=2)
    want = np.linalg.det(Dm) / 6.0
    scale = np.abs(Dm).max(axis=(1, 2)) ** 3
    assert np.all(np.abs(got - want) <= 1e-14 * scale)
    assert np.all(np.sign(got[np.abs(want) > 1e-12 * scale])
                  == np.sign(want[np.abs(want) > 1e-12 * scale]))


def test_orientation_conventions_and_exact_cases():
    x = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0.3, 0.3, 0]], dtype=float)
    vols = LA.tet_signed_volumes(x, np.array([[0, 1, 2, 3], [0, 2, 1, 3], [0, 1, 2, 4]]))
    assert vols.tolist() == [1.0 / 6.0, -1.0 / 6.0, 0.0]
    assert LA.tet_signed_volumes(x, np.zeros((0, 4), np.int64)).shape == (0,)


def test_det3_and_cofactor3_match_numpy():
    rng = np.random.default_rng(4)
    for _ in range(20):
        A = rng.normal(size=(3, 3))
        assert LA.det3(A) == pytest.approx(np.linalg.det(A), rel=1e-12, abs=1e-14)
        C = np.empty((3, 3))
        LA.cofactor3(A, C)
        np.testing.assert_allclose(C, np.linalg.det(A) * np.linalg.inv(A).T, rtol=1e-10,
                                   atol=1e-12)


def test_every_floating_point_volume_is_the_kernel():
    x, tets = _random_tets(7)
    want = LA.tet_signed_volumes(x, tets)
    assert surface_volumes(x, tets).tobytes() == want.tobytes()
    assert surface_volumes(x.tolist(), tets.tolist()).tobytes() == want.tobytes()
    signs = np.empty(len(tets), np.int8)
    vols = np.empty(len(tets))
    KI.tet_orientations(x, tets, signs, vols)
    assert vols.tobytes() == want.tobytes()
    # the exact orientation agrees with the float sign away from zero volume
    clear = np.abs(want) > 1e-9 * np.abs(x).max() ** 3
    assert (signs[clear] == np.sign(want[clear])).all()


def test_generated_boxes_are_positively_oriented():
    points, tets = box_tet_mesh(3, 2, 2, size=(1.0, 2.0, 0.5))
    vol = LA.tet_signed_volumes(points, tets)
    assert (vol > 0).all() and vol.sum() == pytest.approx(1.0)
