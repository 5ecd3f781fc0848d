"""input/tutorial/: each lesson scene runs a bounded number of steps, and every frame
passes ``check --frames`` (exact: no crossing boundary edges, no inverted triangle of an
elastic body, no vertex beyond a line) and an independent check of the frames: the
crossing test of every boundary-edge pair by brute force, in plain float arithmetic with
a margin that can only miss contacts closer than round-off."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from ipcsim.io.vtk import read_frame, read_series
from ipcsim.model.surface import boundary_edges

LESSONS = ("1_mass_spring", "2_dirichlet", "3_contact", "4_friction", "5_mov_dirichlet",
           "6_inv_free", "7_self_contact", "8_self_friction")


def _cross(p, q, r, s) -> bool:
    """Whether the closed segments pq and rs meet (orientation signs, floats)."""
    def orient(a, b, c):
        return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    d1, d2, d3, d4 = orient(r, s, p), orient(r, s, q), orient(p, q, r), orient(p, q, s)
    return d1 * d2 < 0 and d3 * d4 < 0


def _independent_problems(vtu) -> int:
    mesh = read_frame(vtu)
    x = np.asarray(mesh.points)[:, :2]
    tris = next(c.data for c in mesh.cells if c.type == "triangle")
    edges = boundary_edges(tris)
    bad = 0
    for i in range(len(edges)):
        for j in range(i + 1, len(edges)):
            if len(set(edges[i]) | set(edges[j])) == 4:
                bad += _cross(*x[edges[i]], *x[edges[j]])
    return bad


@pytest.mark.parametrize("lesson", LESSONS)
def test_lesson_runs_with_clean_frames(repo_root, tmp_path, lesson):
    scene = repo_root / "input" / "tutorial" / f"{lesson}.toml"
    out = tmp_path / "out"
    run = subprocess.run([sys.executable, "-m", "ipcsim", "run", str(scene), "-o", str(out),
                          "--set", "time.duration=0.6"], capture_output=True, text=True,
                         cwd=repo_root, check=False)
    assert run.returncode == 0, run.stderr
    check = subprocess.run([sys.executable, "-m", "ipcsim", "check", "--frames", str(out)],
                           capture_output=True, text=True, cwd=repo_root, check=False)
    assert check.returncode == 0, check.stdout + check.stderr
    series = read_series(out / "frames" / "series.pvd")
    assert len(series) > 20
    assert sum(_independent_problems(vtu) for _, vtu in series) == 0
