"""Mesh readers: every format, and every failure a MeshError naming the file."""

from __future__ import annotations

import meshio
import numpy as np
import pytest

from ipcsim.errors import MeshError
from ipcsim.model import mesh_io
from ipcsim.model.generate import box_tet_mesh, write_msh


def _expect_mesh_error(fn, *args, match: str, path=None):
    with pytest.raises(MeshError, match=match) as info:
        fn(*args)
    if path is not None:
        assert str(path) in str(info.value)
    return info.value


# ----------------------------------------------------------------------------- tet meshes


def test_msh41_round_trip(tmp_path):
    points, tets = box_tet_mesh(2, 2, 2)
    path = write_msh(tmp_path / "box.msh", points, tets)
    assert path.read_text().startswith("$MeshFormat\n4.1 0 8")
    p, t = mesh_io.read_tet_mesh(path)
    assert np.array_equal(p, points) and np.array_equal(t, tets)
    assert t.dtype == np.int64 and p.dtype == np.float64


@pytest.mark.parametrize("fmt,suffix", [("gmsh22", ".msh"), ("vtk", ".vtk"), ("vtu", ".vtu")])
def test_other_tet_formats(tmp_path, fmt, suffix):
    points, tets = box_tet_mesh(2, 1, 1)
    path = tmp_path / f"box{suffix}"
    kwargs = {"binary": False} if fmt == "gmsh22" else {}
    meshio.write(str(path), meshio.Mesh(points, [("tetra", tets)]), file_format=fmt, **kwargs)
    p, t = mesh_io.read_tet_mesh(path)
    assert np.allclose(p, points) and np.array_equal(t, tets)


def test_msh_with_surface_block_and_extra_cells(tmp_path):
    """The original's files carry a $Surface block; Gmsh files may also hold triangles."""
    points, tets = box_tet_mesh(1, 1, 1)
    mesh = meshio.Mesh(points, [("triangle", np.array([[0, 1, 2]])), ("tetra", tets)])
    path = tmp_path / "mixed.msh"
    meshio.write(str(path), mesh, file_format="gmsh22", binary=False)
    with open(path, "a") as f:
        f.write("$Surface\n1\n1 2 3\n$EndSurface\n")
    p, t = mesh_io.read_tet_mesh(path)
    assert np.array_equal(t, tets)


def test_example_meshes_read(ipc_examples):
    for path in sorted(ipc_examples.joinpath("input").rglob("*.msh")):
        points, tets = mesh_io.read_tet_mesh(path)
        assert len(points) > 0 and len(tets) > 0
        assert tets.min() == 0 and tets.max() == len(points) - 1


def test_tetgen_zero_and_one_based(tmp_path):
    points, tets = box_tet_mesh(1, 1, 2)
    for base in (0, 1):
        stem = tmp_path / f"box{base}"
        node = [f"{len(points)} 3 0 0"] + [f"{i + base} {x} {y} {z}  # c"
                                           for i, (x, y, z) in enumerate(points)]
        ele = [f"{len(tets)} 4 0"] + [f"{i + base} " + " ".join(str(v + base) for v in t)
                                      for i, t in enumerate(tets)]
        stem.with_suffix(".node").write_text("\n".join(node) + "\n")
        stem.with_suffix(".ele").write_text("# tetgen\n" + "\n".join(ele) + "\n")
        for path in (stem.with_suffix(".ele"), stem):  # `<base>.ele` or `<base>`
            p, t = mesh_io.read_tet_mesh(path)
            assert np.allclose(p, points) and np.array_equal(t, tets)


def test_tetgen_truncated(tmp_path):
    (tmp_path / "b.node").write_text("4 3 0 0\n0 0 0 0\n1 1 0 0\n")
    (tmp_path / "b.ele").write_text("1 4 0\n0 0 1 2 3\n")
    _expect_mesh_error(mesh_io.read_tet_mesh, tmp_path / "b.ele", match="truncated")


def test_truncated_msh(tmp_path):
    points, tets = box_tet_mesh(2, 2, 2)
    full = write_msh(tmp_path / "full.msh", points, tets).read_text().splitlines()
    for cut in (6, 20, len(full) // 2, len(full) - 10):
        path = tmp_path / f"cut{cut}.msh"
        path.write_text("\n".join(full[:cut]) + "\n")
        err = _expect_mesh_error(mesh_io.read_tet_mesh, path, 12, match="cannot read", path=path)
        assert err.line == 12  # the scene line that asked for the file


def test_missing_and_garbage_files(tmp_path):
    _expect_mesh_error(mesh_io.read_tet_mesh, tmp_path / "nope.msh", match="not found")
    garbage = tmp_path / "garbage.msh"
    garbage.write_bytes(bytes(range(256)) * 4)
    _expect_mesh_error(mesh_io.read_tet_mesh, garbage, match="cannot read", path=garbage)


def test_nan_coordinates(tmp_path):
    points, tets = box_tet_mesh(1, 1, 1)
    points[3, 1] = np.nan
    path = write_msh(tmp_path / "nan.msh", points, tets)
    _expect_mesh_error(mesh_io.read_tet_mesh, path, match="NaN", path=path)
    obj = tmp_path / "nan.obj"
    obj.write_text("v 0 0 0\nv 1 inf 0\nv 0 0 1\nf 1 2 3\n")
    _expect_mesh_error(mesh_io.read_obj, obj, match="NaN", path=obj)


def test_inverted_and_degenerate_tets(tmp_path):
    points, tets = box_tet_mesh(2, 1, 1)
    inverted = tets.copy()
    inverted[3] = inverted[3, [1, 0, 2, 3]]
    path = write_msh(tmp_path / "inv.msh", points, inverted)
    _expect_mesh_error(mesh_io.read_tet_mesh, path, match="inverted.*tet 4", path=path)
    flat = tets.copy()
    flat[0, 3] = flat[0, 2]  # a repeated vertex: zero volume
    path = write_msh(tmp_path / "flat.msh", points, flat)
    _expect_mesh_error(mesh_io.read_tet_mesh, path, match="zero volume", path=path)


def test_triangle_only_mesh_is_not_a_tet_mesh(tmp_path):
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=float)
    path = tmp_path / "tri.msh"
    meshio.write(str(path), meshio.Mesh(points, [("triangle", np.array([[0, 1, 2]]))]),
                 file_format="gmsh", binary=False)
    _expect_mesh_error(mesh_io.read_tet_mesh, path, match="no tetrahedra.*triangle", path=path)


def test_unreferenced_vertices_are_dropped(tmp_path):
    points, tets = box_tet_mesh(1, 1, 1)
    extra = np.vstack([[9.0, 9.0, 9.0], points])  # vertex 0 is used by no tet
    path = write_msh(tmp_path / "extra.msh", extra, tets + 1)
    p, t = mesh_io.read_tet_mesh(path)
    assert np.array_equal(p, points) and np.array_equal(t, tets)


# ----------------------------------------------------------------------------- codim meshes


def test_obj_triangles_and_errors(tmp_path):
    good = tmp_path / "good.obj"
    good.write_text("o thing\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\ns off\nf 1 2 3\nf 2 4 3\n")
    p, t = mesh_io.read_obj(good)
    assert p.shape == (4, 3) and t.tolist() == [[0, 1, 2], [1, 3, 2]]
    quad = tmp_path / "quad.obj"
    quad.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 1 2 4 3\n")
    _expect_mesh_error(mesh_io.read_obj, quad, match="not triangles", path=quad)
    out = tmp_path / "out.obj"
    out.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n")
    _expect_mesh_error(mesh_io.read_obj, out, match="outside", path=out)


def test_obj_meshio_rejects_falls_back(tmp_path):
    """meshio refuses a normal count different from the vertex count; libigl does not."""
    path = tmp_path / "normals.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n")
    p, t = mesh_io.read_obj(path)
    assert p.shape == (3, 3) and t.tolist() == [[0, 1, 2]]


def test_seg_reader(tmp_path):
    path = tmp_path / "e.seg"
    path.write_text("# edges\nv 0 0 0\nv 1 0 0\nv 1 1 0\ns 1 2\ns 3 2\n")
    p, e = mesh_io.read_seg(path)
    assert p.shape == (3, 3) and e.tolist() == [[0, 1], [2, 1]]
    bad = tmp_path / "bad.seg"
    bad.write_text("v 0 0 0\nv 1 0 0\ns 1 3\n")
    _expect_mesh_error(mesh_io.read_seg, bad, match="outside", path=bad)
    self_loop = tmp_path / "loop.seg"
    self_loop.write_text("v 0 0 0\nv 1 0 0\ns 2 2\n")
    _expect_mesh_error(mesh_io.read_seg, self_loop, match="degenerate")


def test_seg_and_pt_fall_back_to_obj(mesh_dir):
    p, e = mesh_io.read_seg(mesh_dir / "tri.seg")  # tri.seg does not exist: tri.obj's edges
    assert p.shape == (3, 3) and e.tolist() == [[0, 1], [0, 2], [1, 2]]
    pts = mesh_io.read_pt(mesh_dir / "tri.pt")
    assert np.array_equal(pts, p)
    _expect_mesh_error(mesh_io.read_seg, mesh_dir / "none.seg", match="nor the fallback")
    _expect_mesh_error(mesh_io.read_pt, mesh_dir / "none.pt", match="nor the fallback")


def test_pt_reader_ignores_faces(tmp_path):
    path = tmp_path / "p.pt"
    path.write_text("v 0 0 0\nv 1 2 3\nvn 0 0 1\nf 1 2 1\n")
    assert mesh_io.read_pt(path).tolist() == [[0, 0, 0], [1, 2, 3]]


def test_read_shape_surface_needs_triangles(tmp_path):
    path = tmp_path / "pts.obj"
    path.write_text("v 0 0 0\nv 1 0 0\n")
    _expect_mesh_error(mesh_io.read_shape, path, "surface", 3, match="no triangles")


def test_example_codim_meshes(ipc_examples):
    tri = ipc_examples / "input" / "triMeshes"
    p, e = mesh_io.read_seg(tri / "triangle.seg")  # not in the repository: .obj fallback
    assert len(p) == 3 and len(e) == 3
    assert mesh_io.read_pt(tri / "triangle.pt").shape == (3, 3)
    p, t = mesh_io.read_obj(tri / "cube.obj")
    assert p.shape == (8, 3) and t.shape == (12, 3)
    frame = mesh_io.read_frame_positions(ipc_examples / "input/segMeshes/sequence/0.seg", "seg")
    assert frame.shape == (3, 3)


# ----------------------------------------------------------------------------- restart


def test_status_file(tmp_path):
    pos = np.arange(6, dtype=float).reshape(2, 3) / 7
    vel = -pos
    lines = ["timestep 12", "", "position 2 3"] + [" ".join(f"{v:.20g}" for v in r) for r in pos]
    lines += ["", "velocity 6"] + [f"{v:.20g}" for v in vel.ravel()]
    lines += ["", "acceleration 2 3", "0 0 0", "0 0 0", "", "dx_Elastic 2 3", "0 0 0", "0 0 0"]
    path = tmp_path / "status12"
    path.write_text("\n".join(lines) + "\n")
    step, p, v = mesh_io.read_status(path)
    assert step == 12 and np.array_equal(p, pos) and np.array_equal(v, vel)
    path.write_text("\n".join(lines[:6]) + "\n")
    _expect_mesh_error(mesh_io.read_status, path, match="velocity", path=path)


def test_indices_out_of_range(tmp_path):
    points, tets = box_tet_mesh(1, 1, 1)
    bad = tets.copy()
    bad[2, 1] = 41  # node 42 of 8
    path = write_msh(tmp_path / "oor.msh", points, bad)
    _expect_mesh_error(mesh_io.read_tet_mesh, path, match="41|42", path=path)
    (tmp_path / "t.node").write_text("4 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n")
    (tmp_path / "t.ele").write_text("1 4 0\n0 0 1 2 4\n")
    _expect_mesh_error(mesh_io.read_tet_mesh, tmp_path / "t.ele", match="outside 1..4")


def test_every_example_obj_reads_as_meshio_reads_it_without_importing_it():
    """The own OBJ parser gives meshio's arrays, bit for bit, on every OBJ of the
    original's example tree that meshio reads (voro_sphere.obj it cannot), and a scene
    of OBJ obstacles never imports meshio (30–40 ms of a start)."""
    import subprocess
    import sys

    from examples import IPC_EXAMPLES_FULL

    files = sorted(IPC_EXAMPLES_FULL.rglob("*.obj")) if IPC_EXAMPLES_FULL.is_dir() else []
    if not files:
        pytest.skip("../shared/ipc-examples-full is not present")
    compared = 0
    for path in files:
        try:
            mesh = meshio.obj.read(str(path))
        except Exception:
            continue
        p, t = mesh_io.read_obj(path)
        np.testing.assert_array_equal(p, mesh.points, err_msg=str(path))
        tris = [c.data for c in mesh.cells]
        np.testing.assert_array_equal(t, np.concatenate(tris) if tris else np.zeros((0, 3)),
                                      err_msg=str(path))
        compared += 1
    assert compared >= 40
    code = (f"import sys\nfrom ipcsim.model import mesh_io\n"
            f"mesh_io.read_obj({str(files[0])!r})\nprint('meshio' in sys.modules)\n")
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True).stdout.strip() == "False"


def test_an_obj_the_own_parser_refuses_is_read_by_meshio(tmp_path, monkeypatch):
    """Where the own parser raises (here: made to), meshio's reading is used; where both
    refuse, the own parser's message is the one shown."""
    obj = tmp_path / "tri.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")

    def refuse(text, path, line):
        raise MeshError(path, line, "own parser refuses")

    monkeypatch.setattr(mesh_io, "_parse_obj", refuse)
    p, t = mesh_io.read_obj(obj)
    assert p.shape == (3, 3) and t.tolist() == [[0, 1, 2]]
    obj.write_text("v zero 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")  # meshio refuses too
    _expect_mesh_error(mesh_io.read_obj, obj, match="own parser refuses", path=obj)
