"""Broad phase and CCD timings on the two-cube contact scene, with ipctk for comparison.

    python -m benchmarks.ccd_broad_phase [--sizes 30 45] [--repeats 7]

Scene (the one of the shared ipctk micro-benchmark): two unit-cube surfaces with n x n quads
per side, two triangles per quad. The top cube is rotated 10° about z, shifted by (0.1, 0.07)
and sits 0.5·d̂ above the bottom one, d̂ = 1e-3 · bounding-box diagonal. Steps:

* approach: the top cube moves down by 3·gap (ending in penetration), every vertex gets
  uniform noise of ±0.1·gap;
* jitter: uniform noise of ±0.4·gap on every vertex, no bulk motion.

Timed (median after one warm-up call, which also compiles): the static broad phase (boxes
grown by d̂), the swept broad phase of each step, and the whole CCD of each step (swept broad
phase + narrow phase), with the α each returns. With ipctk importable, the same for
``compute_collision_free_stepsize`` with its default Tight-Inclusion CCD and with AdditiveCCD.
Threads: numba's default (NUMBA_NUM_THREADS); ipctk's default.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from ipcsim.contact.candidates import find_candidates
from ipcsim.contact.ccd import collision_free_step
from ipcsim.contact.collision_mesh import CollisionMesh
from ipcsim.model.surface import unique_edges


def cube_surface(n):
    """Unit cube surface, n x n quads per side: vertices (6n²+2, 3), outward triangles."""
    ticks = np.arange(n + 1)
    i, j, k = np.meshgrid(ticks, ticks, ticks, indexing="ij")
    boundary = (np.minimum(np.minimum(i, j), k) == 0) | (np.maximum(np.maximum(i, j), k) == n)
    number = np.full((n + 1,) * 3, -1, np.int64)
    number[boundary] = np.arange(np.count_nonzero(boundary))
    verts = np.stack([i[boundary], j[boundary], k[boundary]], axis=1) / n
    u, v = (a.ravel() for a in np.meshgrid(np.arange(n), np.arange(n), indexing="ij"))
    tris = []
    for axis in range(3):
        others = [a for a in range(3) if a != axis]
        for side in (0, n):
            def vid(a, b):
                idx = [None, None, None]
                idx[axis] = np.full_like(a, side)
                idx[others[0]], idx[others[1]] = a, b
                return number[idx[0], idx[1], idx[2]]
            c00, c10, c11, c01 = vid(u, v), vid(u + 1, v), vid(u + 1, v + 1), vid(u, v + 1)
            tris += [np.stack([c00, c10, c11], 1), np.stack([c00, c11, c01], 1)]
    tris = np.concatenate(tris)
    normal = np.cross(verts[tris[:, 1]] - verts[tris[:, 0]], verts[tris[:, 2]] - verts[tris[:, 0]])
    inward = np.einsum("ij,ij->i", normal, verts[tris].mean(axis=1) - 0.5) < 0
    tris[inward] = tris[inward][:, ::-1]
    return verts, tris


def two_cube_scene(n, angle_deg=10.0):
    """(V, F, E, top mask, d̂, gap) of the two-cube scene."""
    v0, f0 = cube_surface(n)
    th = np.deg2rad(angle_deg)
    rot = np.array([[np.cos(th), -np.sin(th), 0.0], [np.sin(th), np.cos(th), 0.0], [0, 0, 1]])
    v1 = (v0 - 0.5) @ rot.T + 0.5
    lo = np.minimum(v0.min(0), v1.min(0))
    hi = np.maximum(v0.max(0), v1.max(0)) + np.array([0.1, 0.07, 1.0])
    dhat = 1e-3 * float(np.linalg.norm(hi - lo))
    gap = 0.5 * dhat
    v1 = v1 + np.array([0.1, 0.07, 1.0 + gap])
    V = np.vstack([v0, v1])
    F = np.vstack([f0, f0 + len(v0)])
    top = np.arange(len(V)) >= len(v0)
    return V, F, unique_edges(F), top, dhat, gap


def steps(V, top, gap, seed=0):
    rng = np.random.default_rng(seed)
    approach = V.copy()
    approach[top, 2] -= 3 * gap
    approach += rng.uniform(-0.1 * gap, 0.1 * gap, V.shape)
    jitter = V + rng.uniform(-0.4 * gap, 0.4 * gap, V.shape)
    return approach, jitter


def median_ms(fn, repeats):
    out = fn()  # warm-up (and compile)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(times)), out


def run(n, repeats):
    V, F, E, top, dhat, gap = two_cube_scene(n)
    mesh = CollisionMesh.of(len(V), np.arange(len(V)), E, F)
    X1, Xj = steps(V, top, gap)
    rows = []
    t, (pt, ee) = median_ms(lambda: find_candidates(mesh, V, dhat), repeats)
    rows.append(("broad phase static (d̂)", t, f"PT {len(pt)}, EE {len(ee)}"))
    for name, Xe in (("approach", X1), ("jitter", Xj)):
        t, (pt, ee) = median_ms(lambda: find_candidates(mesh, V, 0.0, x1=Xe), repeats)
        rows.append((f"broad phase swept, {name}", t, f"PT {len(pt)}, EE {len(ee)}"))
        t, a = median_ms(lambda: collision_free_step(mesh, V, Xe), repeats)
        rows.append((f"CCD total, {name}", t, f"alpha {a:.4f}"))
    try:
        import ipctk
    except ImportError:
        ipctk = None
    if ipctk is not None:
        f = np.asfortranarray
        mesh = ipctk.CollisionMesh(f(V), f(E.astype(np.int32)), f(F.astype(np.int32)))
        XV = f(V)

        def ipctk_static():
            c = ipctk.Candidates()
            c.build(mesh, XV, 0.5 * dhat)
            return c
        t, c = median_ms(ipctk_static, repeats)
        rows.append(("ipctk broad phase static", t,
                     f"PT {len(c.fv_candidates)}, EE {len(c.ee_candidates)}"))
        for name, Xe in (("approach", X1), ("jitter", Xj)):
            XE = f(Xe)
            t, a = median_ms(lambda: ipctk.compute_collision_free_stepsize(mesh, XV, XE),
                             max(3, repeats // 2))
            rows.append((f"ipctk CCD total (TI), {name}", t, f"alpha {a:.4f}"))
            accd = ipctk.AdditiveCCD()
            t, a = median_ms(lambda: ipctk.compute_collision_free_stepsize(
                mesh, XV, XE, 0.0, ipctk.LBVH(), accd), repeats)
            rows.append((f"ipctk CCD total (ACCD), {name}", t, f"alpha {a:.4f}"))
    print(f"\nn = {n}: {len(V)} surface vertices, {len(E)} edges, {len(F)} triangles, "
          f"d̂ = {dhat:.4g}")
    print(f"| {'kernel':36s} | median ms | result |")
    print(f"|{'-' * 38}|-----------|--------|")
    for name, t, extra in rows:
        print(f"| {name:36s} | {t:9.1f} | {extra} |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[30, 45])
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args(argv)
    try:
        import numba
        print(f"numba threads: {numba.get_num_threads()}")
    except ImportError:
        pass
    for n in args.sizes:
        run(n, args.repeats)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
