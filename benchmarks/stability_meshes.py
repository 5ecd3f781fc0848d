"""Tet meshes of the stability suite that a plain box is not: graded boxes with cells
removed (the slot's U-shaped obstacle, the chain's square-frame links) and the placement
of an interlocked chain.

A graded box is ``box_tet_mesh`` on a grid of unit cells whose vertex coordinates are then
mapped axis by axis onto given breakpoints. Each cell stays an axis-aligned box, so every
tet keeps its positive orientation and the mesh stays conforming; removing whole cells
(their 6 tets) cuts holes without creating new vertices.
"""

from __future__ import annotations

import numpy as np

from ipcsim.model.generate import box_tet_mesh


def graded_box_mesh(xs, ys, zs, removed_cells=()) -> tuple[np.ndarray, np.ndarray]:
    """Tet mesh of the grid with vertex coordinates ``xs`` × ``ys`` × ``zs`` (increasing),
    without the cells (i, j, k) in ``removed_cells``. Unused vertices are dropped."""
    xs, ys, zs = (np.asarray(a, dtype=float) for a in (xs, ys, zs))
    nx, ny, nz = len(xs) - 1, len(ys) - 1, len(zs) - 1
    unit, tets = box_tet_mesh(nx, ny, nz, size=(nx, ny, nz))
    ijk = np.rint(unit).astype(np.int64)
    points = np.stack([xs[ijk[:, 0]], ys[ijk[:, 1]], zs[ijk[:, 2]]], axis=1)
    # box_tet_mesh numbers cells (i, j, k) as i·ny·nz + j·nz + k, 6 consecutive tets each
    keep = np.ones(len(tets) // 6, dtype=bool)
    for i, j, k in removed_cells:
        keep[(i * ny + j) * nz + k] = False
    tets = tets.reshape(-1, 6, 4)[keep].reshape(-1, 4)
    used = np.unique(tets)
    renumber = np.full(len(points), -1, dtype=np.int64)
    renumber[used] = np.arange(len(used))
    return points[used], renumber[tets]


def slot_mesh(size: float, clearance: float, wall: float, depth: float,
              floor: float) -> tuple[np.ndarray, np.ndarray]:
    """U-shaped obstacle with an open slot of width size·(1 + clearance) centred on x = 0,
    from y = 0 (the slot's floor) up to y = depth; the base reaches down to y = −floor and
    the whole piece spans z ∈ [−0.75 size, 0.75 size]."""
    g = 0.5 * size * (1.0 + clearance)
    return graded_box_mesh([-g - wall, -g, g, g + wall], [-floor, 0.0, depth],
                           [-0.75 * size, 0.75 * size], removed_cells=[(1, 1, 0)])


def link_mesh(bar: float, hole_w: float, hole_h: float,
              thickness: float) -> tuple[np.ndarray, np.ndarray]:
    """A rectangular frame (chain link) in the xy plane, one cell thick in z: outer size
    (2 bar + hole_w) × (2 bar + hole_h), corner at the origin."""
    return graded_box_mesh([0, bar, bar + hole_w, 2 * bar + hole_w],
                           [0, bar, bar + hole_h, 2 * bar + hole_h], [0, thickness],
                           removed_cells=[(1, 1, 0)])


def chain_placements(n_links: int, bar: float, hole_w: float, hole_h: float,
                     thickness: float, top: float, gap: float):
    """(translation, rotation about y in degrees) of each link of a hanging chain, link 0
    highest. Odd links are turned 90° about y; each link's top bar sits in the previous
    link's hole, ``gap`` above that hole's lower edge, so consecutive links interlock and
    nothing touches at the start."""
    width = 2 * bar + hole_w
    height = 2 * bar + hole_h
    pitch = height - 2 * bar - gap  # y0(k) − y0(k+1)
    out = []
    for k in range(n_links):
        y = top - height - k * pitch
        if k % 2 == 0:  # in the xy plane, centred on x = z = 0
            out.append(((-0.5 * width, y, -0.5 * thickness), 0.0))
        else:  # turned into the yz plane: R_y(90°) maps (x, z) -> (z, −x)
            out.append(((-0.5 * thickness, y, 0.5 * width), 90.0))
    return out
