"""Scatter-adds: COO values into a fixed sparse pattern; per-stencil gradients into a
flat gradient."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def scatter_add(data, slots, vals, keep):
    """data[slots[k]] += vals[keep[k]] for every kept triplet k."""
    for k in range(slots.shape[0]):
        data[slots[k]] += vals[keep[k]]


@njit(cache=True)
def scatter_stencil_gradients(G, pt_pairs, ee_pairs, n_vertices):
    """Flat (3n,) gradient from per-pair local gradients ``G`` (k + j, 12): row i belongs
    to pt_pairs[i] (i < k), then to ee_pairs[i − k]. Serial, so race-free; the local
    gradients themselves are computed in parallel by the caller."""
    k = pt_pairs.shape[0]
    grad = np.zeros(3 * n_vertices)
    for i in range(G.shape[0]):
        pair = pt_pairs[i] if i < k else ee_pairs[i - k]
        for v in range(4):
            for a in range(3):
                grad[3 * pair[v] + a] += G[i, 3 * v + a]
    return grad
