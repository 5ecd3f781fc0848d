"""Scatter-add of COO values into a fixed sparse pattern."""

from __future__ import annotations

from numba import njit


@njit(cache=True)
def scatter_add(data, slots, vals, keep):
    """data[slots[k]] += vals[keep[k]] for every kept triplet k."""
    for k in range(slots.shape[0]):
        data[slots[k]] += vals[keep[k]]
