"""Edge-edge mollifier of Li et al. 2020 (IPC), as in ipctk.

Nearly parallel edges make the edge-edge distance non-smooth (its closest-feature type
flips), so the edge-edge barrier is multiplied by

    m(c) = (2 − c/ε)(c/ε)  for c < ε,   1 otherwise,
    c    = |(ea1 − ea0)×(eb1 − eb0)|²          (at the current positions),
    ε    = 1e-3 |ea0 − ea1|² |eb0 − eb1|²      (eps_x, from the REST positions).

m is C¹ at c = ε (m = 1, m' = 0) and m(0) = 0. Derivatives w.r.t. the 12 edge-edge DOFs
(ea0, ea1, eb0, eb1):  ∇m = m'(c) ∇c,  ∇²m = m'(c) ∇²c + m''(c) ∇c ∇cᵀ.
"""

from __future__ import annotations

import numpy as np
from ipcsim.compiler.jit import njit

from ipcsim.kernels.algebra.linalg import cross3, dot3, squared_norm3, sub3
from ipcsim.kernels.contact.distance import edge_directions

EE_MOLLIFIER_SCALE = 1e-3


@njit(cache=True, error_model="numpy")
def edge_edge_mollifier_threshold(ea0_rest, ea1_rest, eb0_rest, eb1_rest):
    # ε = 1e-3 |ea0 − ea1|² |eb0 − eb1|²  (rest positions)
    return (EE_MOLLIFIER_SCALE * squared_norm3(sub3(ea0_rest, ea1_rest))
            * squared_norm3(sub3(eb0_rest, eb1_rest)))


@njit(cache=True, error_model="numpy")
def edge_edge_mollifier_thresholds(x_rest, ee_pairs):
    """ε for every edge-edge pair: x_rest (n, 3), ee_pairs (j, 4) int64 -> (j,)."""
    out = np.empty(ee_pairs.shape[0])
    for k in range(ee_pairs.shape[0]):  # O(j), once per candidate set: serial
        i0, i1, j0, j1 = ee_pairs[k, 0], ee_pairs[k, 1], ee_pairs[k, 2], ee_pairs[k, 3]
        out[k] = edge_edge_mollifier_threshold(x_rest[i0], x_rest[i1], x_rest[j0], x_rest[j1])
    return out


# --- c = |u×v|², u = ea1 − ea0, v = eb1 − eb0 ----------------------------------------------

@njit(cache=True, error_model="numpy")
def edge_edge_cross_sq(ea0, ea1, eb0, eb1):
    # c = |(ea1 − ea0)×(eb1 − eb0)|²
    _, _, n = edge_directions(ea0, ea1, eb0, eb1)
    return squared_norm3(n)


@njit(cache=True, error_model="numpy")
def edge_edge_cross_sq_gradient(ea0, ea1, eb0, eb1):
    # n = u×v:  ∂c/∂u = 2 v×n,  ∂c/∂v = 2 n×u;   ∂/∂ea0 = −∂/∂u, ∂/∂ea1 = ∂/∂u, same for b, v
    u, v, n = edge_directions(ea0, ea1, eb0, eb1)
    gu = cross3(v, n)
    gv = cross3(n, u)
    g = np.empty(12)
    for a in range(3):
        g[a] = -2.0 * gu[a]
        g[3 + a] = 2.0 * gu[a]
        g[6 + a] = -2.0 * gv[a]
        g[9 + a] = 2.0 * gv[a]
    return g


@njit(cache=True, error_model="numpy")
def edge_edge_cross_sq_hessian(ea0, ea1, eb0, eb1):
    # c = |u|²|v|² − (u·v)²  (Lagrange):
    #   ∂²c/∂u² = 2|v|² I − 2 v vᵀ,  ∂²c/∂v² = 2|u|² I − 2 u uᵀ,
    #   ∂²c/∂u∂v = 4 u vᵀ − 2 v uᵀ − 2 (u·v) I
    # then H = Dᵀ H_uv D with u = ea1 − ea0, v = eb1 − eb0 (signs −1, +1 per endpoint)
    u, v, _ = edge_directions(ea0, ea1, eb0, eb1)
    uu = dot3(u, u)
    vv = dot3(v, v)
    uv = dot3(u, v)
    Huu = np.empty((3, 3))
    Hvv = np.empty((3, 3))
    Huv = np.empty((3, 3))
    for a in range(3):
        for b in range(3):
            dab = 1.0 if a == b else 0.0
            Huu[a, b] = 2.0 * vv * dab - 2.0 * v[a] * v[b]
            Hvv[a, b] = 2.0 * uu * dab - 2.0 * u[a] * u[b]
            Huv[a, b] = 4.0 * u[a] * v[b] - 2.0 * v[a] * u[b] - 2.0 * uv * dab
    H = np.empty((12, 12))
    for i in range(4):
        si = -1.0 if (i % 2 == 0) else 1.0  # ea0, eb0: −1; ea1, eb1: +1
        for j in range(4):
            sj = -1.0 if (j % 2 == 0) else 1.0
            for a in range(3):
                for b in range(3):
                    if i < 2 and j < 2:
                        h = Huu[a, b]
                    elif i >= 2 and j >= 2:
                        h = Hvv[a, b]
                    elif i < 2:
                        h = Huv[a, b]
                    else:
                        h = Huv[b, a]
                    H[3 * i + a, 3 * j + b] = si * sj * h
    return H


# --- scalar mollifier m(c; ε) --------------------------------------------------------------

@njit(cache=True, error_model="numpy")
def mollifier_scalar(c, eps_x):
    # m = (2 − c/ε)(c/ε) for c < ε, else 1
    if c < eps_x:
        r = c / eps_x
        return (2.0 - r) * r
    return 1.0


@njit(cache=True, error_model="numpy")
def mollifier_scalar_first_derivative(c, eps_x):
    # m' = (2/ε)(1 − c/ε) for c < ε, else 0
    if c < eps_x:
        return 2.0 / eps_x * (1.0 - c / eps_x)
    return 0.0


@njit(cache=True, error_model="numpy")
def mollifier_scalar_second_derivative(c, eps_x):
    # m'' = −2/ε² for c < ε, else 0
    if c < eps_x:
        return -2.0 / (eps_x * eps_x)
    return 0.0


# --- m as a function of the 12 edge-edge DOFs ----------------------------------------------

@njit(cache=True, error_model="numpy")
def edge_edge_mollifier(ea0, ea1, eb0, eb1, eps_x):
    return mollifier_scalar(edge_edge_cross_sq(ea0, ea1, eb0, eb1), eps_x)


@njit(cache=True, error_model="numpy")
def edge_edge_mollifier_gradient(ea0, ea1, eb0, eb1, eps_x):
    # ∇m = m'(c) ∇c
    c = edge_edge_cross_sq(ea0, ea1, eb0, eb1)
    if c >= eps_x:
        return np.zeros(12)
    g = edge_edge_cross_sq_gradient(ea0, ea1, eb0, eb1)
    dm = mollifier_scalar_first_derivative(c, eps_x)
    for i in range(12):
        g[i] *= dm
    return g


@njit(cache=True, error_model="numpy")
def edge_edge_mollifier_hessian(ea0, ea1, eb0, eb1, eps_x):
    # ∇²m = m'(c) ∇²c + m''(c) ∇c ∇cᵀ
    c = edge_edge_cross_sq(ea0, ea1, eb0, eb1)
    if c >= eps_x:
        return np.zeros((12, 12))
    g = edge_edge_cross_sq_gradient(ea0, ea1, eb0, eb1)
    H = edge_edge_cross_sq_hessian(ea0, ea1, eb0, eb1)
    dm = mollifier_scalar_first_derivative(c, eps_x)
    d2m = mollifier_scalar_second_derivative(c, eps_x)
    for i in range(12):
        for j in range(12):
            H[i, j] = dm * H[i, j] + d2m * g[i] * g[j]
    return H
