"""Small dense linear algebra for per-stencil kernels (3-vectors, 12x12 blocks).

Everything here is called a few times per contact pair. Like distance.py, mollifier.py
and contact_barrier.py it compiles with error_model="numpy": a division by zero (a
degenerate edge or triangle, d² = 0) gives inf/nan as in IEEE arithmetic instead of
raising a Python exception inside a parallel loop.
"""

from __future__ import annotations

import numpy as np
from numba import njit


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
