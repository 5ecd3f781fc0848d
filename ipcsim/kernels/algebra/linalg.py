"""Small dense linear algebra for per-stencil kernels (3-vectors, 3x3 determinants, 12x12
blocks), and the one floating-point tet volume (and triangle area) of the package.

Everything here is called a few times per contact pair or tet. Like distance.py, mollifier.py
and contact_barrier.py it compiles with error_model="numpy": a division by zero (a
degenerate edge or triangle, d² = 0) gives inf/nan as in IEEE arithmetic instead of
raising a Python exception inside a parallel loop.
"""

from __future__ import annotations

import numpy as np
from ipcsim.compiler.jit import njit


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
def chain_gradient(g, f1):
    """∇f(s) = f'(s) ∇s for f of a scalar s(x) (a barrier or penalty of d²), in place on
    g = ∇s (f1 = f'(s), any constant factor folded in)."""
    for i in range(g.shape[0]):
        g[i] *= f1
    return g


@njit(cache=True, error_model="numpy", inline="always")
def chain_hessian(H, g, f1, f2, scale):
    """scale · ∇²f(s) = scale (f'(s) ∇²s + f''(s) ∇s ∇sᵀ), in place on H = ∇²s (g = ∇s,
    f1 = f', f2 = f'')."""
    n = g.shape[0]
    for i in range(n):
        for j in range(n):
            H[i, j] = scale * (f1 * H[i, j] + f2 * g[i] * g[j])
    return H


@njit(cache=True, error_model="numpy", inline="always")
def edge_matrix(x, elements, e, D):
    """D = [x1 − x0, x2 − x0, …] (columns) of simplex e (vertices elements[e]), into D:
    (3, 3) for a tet, (2, 2) for a triangle (its x, y parts)."""
    i0 = elements[e, 0]
    for c in range(D.shape[1]):
        ic = elements[e, c + 1]
        for a in range(D.shape[0]):
            D[a, c] = x[ic, a] - x[i0, a]


@njit(cache=True, error_model="numpy")
def tet_signed_volumes(x, tets):
    """Signed volumes (m,) of the tets (m, 4) over positions x (n, 3):
    V = det[x1 − x0, x2 − x0, x3 − x0] / 6 (positive for a positively oriented tet).

    The floating-point volume of the package: the same determinant (``edge_matrix``,
    ``det3``) as the elastic step bound. Its sign is not exact near zero volume; the exact
    orientation predicate is ``intersection.orient3d``."""
    m = tets.shape[0]
    out = np.empty(m)
    D = np.empty((3, 3))
    for e in range(m):
        edge_matrix(x, tets, e, D)
        out[e] = det3(D) / 6.0
    return out


@njit(cache=True, error_model="numpy")
def triangle_signed_areas(x, triangles):
    """Signed areas (m,) of the triangles (m, 3) of a 2D scene over positions x (n, 3),
    in the plane z = 0: A = det[x1 − x0, x2 − x0] / 2 of the x, y parts (positive for a
    counter-clockwise triangle). The floating-point area of the package, as
    ``tet_signed_volumes`` is the volume; the exact sign is ``intersection.orient2d``."""
    m = triangles.shape[0]
    out = np.empty(m)
    for e in range(m):
        a, b, c = triangles[e, 0], triangles[e, 1], triangles[e, 2]
        out[e] = 0.5 * ((x[b, 0] - x[a, 0]) * (x[c, 1] - x[a, 1])
                        - (x[b, 1] - x[a, 1]) * (x[c, 0] - x[a, 0]))
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
    n = H.shape[0]
    w = np.empty(n)
    V = np.empty((n, n))
    symmetric_eigen(H, w, V)
    if w.min() >= 0.0:
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


@njit(cache=True, error_model="numpy")
def project_psd_on_dofs(H, dof):
    """project_psd(H) for a symmetric H that is zero outside the rows and columns ``dof``
    (int array): only that block is decomposed, the rest of the result is zero. Returns
    a new array of H's shape."""
    n = dof.shape[0]
    sub = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            sub[i, j] = H[dof[i], dof[j]]
    P = project_psd(sub)
    out = np.zeros(H.shape)
    for i in range(n):
        for j in range(n):
            out[dof[i], dof[j]] = P[i, j]
    return out


@njit(cache=True, error_model="numpy")
def symmetric_eigen(A, w, V):
    """Eigenvalues w (n,) and orthonormal eigenvectors V (columns, n x n) of the
    symmetric A (read only): A = V diag(w) Vᵀ, w in no particular order.

    Householder reduction to tridiagonal form, then the QL algorithm with implicit
    Wilkinson shifts on it (EISPACK's tred2 and tql2), in place in V, w and one
    off-diagonal vector. For the 6–12 wide blocks of a contact stencil this is twice as
    fast as ``np.linalg.eigh``, whose LAPACK call copies its input, allocates its work
    arrays and asks for their size first; it is also the only LAPACK the kernels used."""
    n = A.shape[0]
    e = np.zeros(n)
    V[:, :] = A
    _tridiagonalize(V, w, e)
    _tridiagonal_ql(V, w, e)


@njit(cache=True, error_model="numpy", inline="always")
def _tridiagonalize(V, d, e):
    # Householder: on entry V holds A; on exit V holds the orthogonal Q of A = Q T Qᵀ,
    # d the diagonal of T and e[1:] its subdiagonal (e[0] = 0). Row i is reduced from
    # the last row up, working on the lower triangle.
    n = V.shape[0]
    for j in range(n):
        d[j] = V[n - 1, j]
    for i in range(n - 1, 0, -1):
        scale = 0.0
        for k in range(i):
            scale += abs(d[k])
        h = 0.0
        if scale == 0.0:  # row already reduced: skip the reflection
            e[i] = d[i - 1]
            for j in range(i):
                d[j] = V[i - 1, j]
                V[i, j] = 0.0
                V[j, i] = 0.0
        else:
            # the Householder vector u (in d[:i]) with H = I − u uᵀ / h, scaled for range
            for k in range(i):
                d[k] /= scale
                h += d[k] * d[k]
            f = d[i - 1]
            g = np.sqrt(h)
            if f > 0.0:
                g = -g
            e[i] = scale * g
            h -= f * g
            d[i - 1] = f - g
            for j in range(i):
                e[j] = 0.0
            # p = A u / h in e, then q = p − (uᵀp / 2h) u, and A ← A − u qᵀ − q uᵀ
            for j in range(i):
                f = d[j]
                V[j, i] = f
                g = e[j] + V[j, j] * f
                for k in range(j + 1, i):
                    g += V[k, j] * d[k]
                    e[k] += V[k, j] * f
                e[j] = g
            f = 0.0
            for j in range(i):
                e[j] /= h
                f += e[j] * d[j]
            hh = f / (h + h)
            for j in range(i):
                e[j] -= hh * d[j]
            for j in range(i):
                f = d[j]
                g = e[j]
                for k in range(j, i):
                    V[k, j] -= f * e[k] + g * d[k]
                d[j] = V[i - 1, j]
                V[i, j] = 0.0
        d[i] = h
    # accumulate the reflections into Q
    for i in range(n - 1):
        V[n - 1, i] = V[i, i]
        V[i, i] = 1.0
        h = d[i + 1]
        if h != 0.0:
            for k in range(i + 1):
                d[k] = V[k, i + 1] / h
            for j in range(i + 1):
                g = 0.0
                for k in range(i + 1):
                    g += V[k, i + 1] * V[k, j]
                for k in range(i + 1):
                    V[k, j] -= g * d[k]
        for k in range(i + 1):
            V[k, i + 1] = 0.0
    for j in range(n):
        d[j] = V[n - 1, j]
        V[n - 1, j] = 0.0
    V[n - 1, n - 1] = 1.0
    e[0] = 0.0


@njit(cache=True, error_model="numpy", inline="always")
def hypot(a, b):
    """√(a² + b²) without overflow or underflow, to within two ulps: the plain formula
    wherever its squares neither overflow nor underflow, else scaled by the larger.
    libm's ``hypot``, which rounds exactly, was a third of a 12 x 12 eigen-decomposition's
    time."""
    a, b = abs(a), abs(b)
    big, small = max(a, b), min(a, b)
    if 1e-150 < big < 1e150:
        return np.sqrt(big * big + small * small)
    if big == 0.0 or big == np.inf:
        return big
    r = small / big
    return big * np.sqrt(1.0 + r * r)


@njit(cache=True, error_model="numpy", inline="always")
def _tridiagonal_ql(V, d, e):
    # QL iterations on the tridiagonal (d, e[1:]) until each off-diagonal entry is below
    # ε times the largest |d| + |e| seen; the rotations are applied to V's columns, so
    # on exit d holds the eigenvalues and V the eigenvectors.
    n = V.shape[0]
    for i in range(1, n):
        e[i - 1] = e[i]
    e[n - 1] = 0.0
    eps = np.finfo(np.float64).eps
    shift = 0.0
    largest = 0.0
    for l in range(n):
        largest = max(largest, abs(d[l]) + abs(e[l]))
        m = l  # the first negligible off-diagonal entry from l on splits the matrix
        while m < n - 1 and abs(e[m]) > eps * largest:
            m += 1
        if m > l:
            for _ in range(64):  # converges in 1–3 iterations per eigenvalue
                # Wilkinson shift from the leading 2 x 2 block
                g = d[l]
                p = (d[l + 1] - g) / (2.0 * e[l])
                r = hypot(p, 1.0)
                if p < 0.0:
                    r = -r
                d[l] = e[l] / (p + r)
                d[l + 1] = e[l] * (p + r)
                dl1 = d[l + 1]
                h = g - d[l]
                for i in range(l + 2, n):
                    d[i] -= h
                shift += h
                # the implicit QL sweep from m up to l, chasing the bulge with rotations
                p = d[m]
                c = c2 = c3 = 1.0
                el1 = e[l + 1]
                s = s2 = 0.0
                for i in range(m - 1, l - 1, -1):
                    c3 = c2
                    c2 = c
                    s2 = s
                    g = c * e[i]
                    h = c * p
                    r = hypot(p, e[i])
                    e[i + 1] = s * r
                    s = e[i] / r
                    c = p / r
                    p = c * d[i] - s * g
                    d[i + 1] = h + s * (c * g + s * d[i])
                    for k in range(n):
                        h = V[k, i + 1]
                        V[k, i + 1] = s * V[k, i] + c * h
                        V[k, i] = c * V[k, i] - s * h
                p = -s * s2 * c3 * el1 * e[l] / dl1
                e[l] = s * p
                d[l] = c * p
                if not abs(e[l]) > eps * largest:
                    break
        d[l] += shift
        e[l] = 0.0


@njit(cache=True)
def ordered_sum(a):
    """Σ a[i] in index order: the same bits whether the caller runs in parallel or not
    (inside a parallel kernel, ``a.sum()`` becomes a parallel reduction)."""
    total = 0.0
    for i in range(a.shape[0]):
        total += a[i]
    return total


# -- a small Newton system as a dense Cholesky factor ------------------------------------
# Below about a hundred DOFs (two tutorial cubes: 48) a sparse factorisation costs more in
# its setup than in its arithmetic; the dense factor of the same matrix takes n³/3
# multiply-adds, a few microseconds.

@njit(cache=True)
def dense_cholesky(indptr, indices, data, L):
    """L Lᵀ = A in place of L (n, n), from the lower triangle of the symmetric CSC matrix
    (indptr, indices, data) (CSR of the upper triangle reads the same). L's strict upper
    triangle is left zero. Returns False at the first pivot that is not positive (or not
    finite): A is not positive definite."""
    n = L.shape[0]
    L[:, :] = 0.0
    for j in range(n):
        for k in range(indptr[j], indptr[j + 1]):
            i = indices[k]
            if i >= j:
                L[i, j] += data[k]
    return cholesky_in_place(L)


@njit(cache=True)
def cholesky_in_place(L):
    """The Cholesky factor of the symmetric A whose lower triangle L (n, n) holds, in
    that lower triangle (the strict upper one is not read, nor written). False at the
    first pivot that is not positive (or not finite): A is not positive definite."""
    n = L.shape[0]
    for j in range(n):
        # L_jj = √(A_jj − Σ_k<j L_jk²),  L_ij = (A_ij − Σ_k<j L_ik L_jk) / L_jj
        d = L[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        if not (d > 0.0 and d < np.inf):
            return False
        d = np.sqrt(d)
        L[j, j] = d
        i = j + 1
        while i + 3 < n:
            # four rows at once: four independent sums share each L_jk (twice as fast
            # at 120 DOFs as one row at a time), each still summed in k order
            s0, s1, s2, s3 = L[i, j], L[i + 1, j], L[i + 2, j], L[i + 3, j]
            for k in range(j):
                ljk = L[j, k]
                s0 -= L[i, k] * ljk
                s1 -= L[i + 1, k] * ljk
                s2 -= L[i + 2, k] * ljk
                s3 -= L[i + 3, k] * ljk
            L[i, j], L[i + 1, j], L[i + 2, j], L[i + 3, j] = s0 / d, s1 / d, s2 / d, s3 / d
            i += 4
        for r in range(i, n):  # the rows left over
            s = L[r, j]
            for k in range(j):
                s -= L[r, k] * L[j, k]
            L[r, j] = s / d
    return True


@njit(cache=True)
def cholesky_solve(L, b, x):
    """x = A⁻¹ b with A = L Lᵀ: forward substitution L y = b, then back substitution
    Lᵀ x = y (x may not be b)."""
    n = L.shape[0]
    for i in range(n):
        s = b[i]
        for k in range(i):
            s -= L[i, k] * x[k]
        x[i] = s / L[i, i]
    for i in range(n - 1, -1, -1):
        s = x[i]
        for k in range(i + 1, n):
            s -= L[k, i] * x[k]
        x[i] = s / L[i, i]


@njit(cache=True)
def dot(a, b):
    """Σ aᵢ bᵢ in index order: one rounding order wherever it is taken (numpy's BLAS
    sums in blocks whose order depends on the build and the machine, and a compiled
    Newton iteration must balance κ exactly as the Python one does)."""
    s = 0.0
    for i in range(a.shape[0]):
        s += a[i] * b[i]
    return s
