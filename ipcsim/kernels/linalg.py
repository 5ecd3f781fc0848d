"""Small dense linear algebra for per-stencil kernels (3-vectors, 3x3 determinants, 12x12
blocks), and the one floating-point tet volume of the package.

Everything here is called a few times per contact pair or tet. Like distance.py, mollifier.py
and contact_barrier.py it compiles with error_model="numpy": a division by zero (a
degenerate edge or triangle, d² = 0) gives inf/nan as in IEEE arithmetic instead of
raising a Python exception inside a parallel loop.
"""

from __future__ import annotations

import numpy as np
from ipcsim.kernels.jit import njit


# 3-vectors are passed as anything indexable (array rows or tuples) and returned as
# tuples: they live in registers, with no heap allocation and no reference counting.

@njit(cache=True, error_model="numpy")
def dot3(a, b):
    # a·b
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True, error_model="numpy")
def cross3(a, b):
    # a×b
    return (a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0])


@njit(cache=True, error_model="numpy")
def point3(x, i):
    # row i of the (n, 3) array x as a tuple: values, not a view (no reference count;
    # a point per call as an array view made the contact kernels 8× slower)
    return (x[i, 0], x[i, 1], x[i, 2])


@njit(cache=True, error_model="numpy")
def sub3(a, b):
    # a − b
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@njit(cache=True, error_model="numpy")
def scale3(s, a):
    # s a
    return (s * a[0], s * a[1], s * a[2])


@njit(cache=True, error_model="numpy")
def squared_norm3(a):
    # |a|²
    return a[0] * a[0] + a[1] * a[1] + a[2] * a[2]


# 3 x 3 matrices and tets. The small ones are inlined at the numba IR level
# (inline="always"): elasticity.py calls them per tet, where a call passing arrays would
# pay reference counting (see the note there).

@njit(cache=True, error_model="numpy", inline="always")
def det3(A):
    """det A of a 3 x 3 array, by cofactor expansion along the first row."""
    return (
        A[0, 0] * (A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1])
        - A[0, 1] * (A[1, 0] * A[2, 2] - A[1, 2] * A[2, 0])
        + A[0, 2] * (A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0])
    )


@njit(cache=True, error_model="numpy", inline="always")
def cofactor3(A, C):
    """C = ∂det(A)/∂A = det(A) A⁻ᵀ (the cofactor matrix of the 3 x 3 A), into C."""
    C[0, 0] = A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1]
    C[0, 1] = A[1, 2] * A[2, 0] - A[1, 0] * A[2, 2]
    C[0, 2] = A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0]
    C[1, 0] = A[0, 2] * A[2, 1] - A[0, 1] * A[2, 2]
    C[1, 1] = A[0, 0] * A[2, 2] - A[0, 2] * A[2, 0]
    C[1, 2] = A[0, 1] * A[2, 0] - A[0, 0] * A[2, 1]
    C[2, 0] = A[0, 1] * A[1, 2] - A[0, 2] * A[1, 1]
    C[2, 1] = A[0, 2] * A[1, 0] - A[0, 0] * A[1, 2]
    C[2, 2] = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]


@njit(cache=True, error_model="numpy", inline="always")
def tet_edge_matrix(x, tets, e, D):
    """D = [x1 − x0, x2 − x0, x3 − x0] (columns) of tet e (vertices tets[e]), into D."""
    i0 = tets[e, 0]
    for c in range(3):
        ic = tets[e, c + 1]
        for a in range(3):
            D[a, c] = x[ic, a] - x[i0, a]


@njit(cache=True, error_model="numpy")
def tet_signed_volumes(x, tets):
    """Signed volumes (m,) of the tets (m, 4) over positions x (n, 3):
    V = det[x1 − x0, x2 − x0, x3 − x0] / 6 (positive for a positively oriented tet).

    The floating-point volume of the package: the same determinant (``tet_edge_matrix``,
    ``det3``) as the elastic step bound. Its sign is not exact near zero volume; the exact
    orientation predicate is ``intersection.orient3d``."""
    m = tets.shape[0]
    out = np.empty(m)
    D = np.empty((3, 3))
    for e in range(m):
        tet_edge_matrix(x, tets, e, D)
        out[e] = det3(D) / 6.0
    return out


@njit(cache=True, error_model="numpy")
def symmetrize_from_upper(H):
    """Copy the upper triangle onto the lower one, in place, and return H."""
    n = H.shape[0]
    for i in range(n):
        for j in range(i + 1, n):
            H[j, i] = H[i, j]
    return H


@njit(cache=True, error_model="numpy")
def project_psd(H):
    """Nearest (Frobenius) positive semi-definite matrix to the symmetric matrix H:
    H = V Λ Vᵀ  ->  V max(Λ, 0) Vᵀ. Returns a new array; H itself is returned as a
    copy when it is already PSD (no reconstruction round-off)."""
    w, V = np.linalg.eigh(H)
    n = H.shape[0]
    if w[0] >= 0.0:
        return H.copy()
    out = np.zeros((n, n))
    for k in range(n):
        lam = w[k]
        if lam <= 0.0:
            continue
        for i in range(n):
            vik = lam * V[i, k]
            for j in range(i, n):
                out[i, j] += vik * V[j, k]
    return symmetrize_from_upper(out)


@njit(cache=True)
def ordered_sum(a):
    """Σ a[i] in index order: the same bits whether the caller runs in parallel or not
    (inside a parallel kernel, ``a.sum()`` becomes a parallel reduction)."""
    total = 0.0
    for i in range(a.shape[0]):
        total += a[i]
    return total
