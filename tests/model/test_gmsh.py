"""Gmsh ASCII text read by ipcsim itself: the same arrays as meshio's reader, and every
file it does not take on left to meshio."""

from __future__ import annotations

import subprocess
import sys

import meshio
import numpy as np
import pytest

from examples import IPC_EXAMPLES_FULL
from ipcsim.errors import MeshError
from ipcsim.model import gmsh, mesh_io
from ipcsim.model.generate import box_tet_mesh, write_msh


def _meshio_arrays(path):
    mesh = meshio.gmsh.read(str(path))
    tets = np.concatenate([c.data for c in mesh.cells if c.type == "tetra"])
    return mesh.points, tets


def _example_meshes():
    root = IPC_EXAMPLES_FULL / "input"
    return sorted(root.rglob("*.msh")) if root.is_dir() else []


@pytest.mark.skipif(not _example_meshes(), reason="../shared/ipc-examples-full is not present")
def test_every_example_mesh_reads_as_meshio_reads_it():
    """Bit for bit: the same coordinates, the same tets in the same order."""
    paths = _example_meshes()
    for path in paths:
        parsed = gmsh.parse(path.read_text())
        assert parsed is not None and parsed.version == "4.1", path
        points, tets = parsed.tetrahedra()
        expected_points, expected_tets = _meshio_arrays(path)
        assert points.dtype == np.float64 and tets.dtype == np.int64
        assert np.array_equal(points, expected_points), path
        assert np.array_equal(tets, expected_tets), path
    assert len(paths) >= 50


def test_a_generated_box_reads_as_meshio_reads_it(tmp_path):
    points, tets = box_tet_mesh(3, 2, 2)
    path = write_msh(tmp_path / "box.msh", points + 0.1, tets)
    own = gmsh.parse(path.read_text()).tetrahedra()
    expected = _meshio_arrays(path)
    assert np.array_equal(own[0], expected[0]) and np.array_equal(own[1], expected[1])


def _msh41(node_tags, coordinates, tets, parametric="0", kind=4):
    lines = ["$MeshFormat", "4.1 0 8", "$EndMeshFormat", "$Nodes",
             f"1 {len(node_tags)} {min(node_tags)} {max(node_tags)}",
             f"3 1 {parametric} {len(node_tags)}", *map(str, node_tags),
             *(" ".join(map(repr, c)) for c in coordinates), "$EndNodes", "$Elements",
             f"1 {len(tets)} 1 {len(tets)}", f"3 1 {kind} {len(tets)}",
             *(" ".join(map(str, [i + 1, *t])) for i, t in enumerate(tets)), "$EndElements"]
    return "\n".join(lines) + "\n"


UNIT_TET = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)]


def test_the_files_it_does_not_take_on_go_to_meshio(tmp_path):
    """Tags other than 1..n in order, parametric nodes, no tetrahedra, MSH 2.2, binary:
    ``tetrahedra`` gives None and read_tet_mesh reads the file with meshio."""
    gapped = _msh41([3, 5, 7, 9], UNIT_TET, [(3, 5, 7, 9)])
    assert gmsh.parse(gapped).tetrahedra() is None
    path = tmp_path / "gapped.msh"
    path.write_text(gapped)
    points, tets = mesh_io.read_tet_mesh(path)
    assert np.array_equal(points, UNIT_TET) and np.array_equal(tets, [[0, 1, 2, 3]])

    assert gmsh.parse(_msh41([1, 2, 3, 4], UNIT_TET, [(1, 2, 3, 4)], kind=2)) \
        .tetrahedra() is None  # a 4-node quadrangle is no tetrahedron

    triangles = _msh41([1, 2, 3, 4], UNIT_TET, [(1, 2, 3)], kind=2)
    assert gmsh.parse(triangles).tetrahedra() is None
    path = tmp_path / "triangles.msh"
    path.write_text(triangles)
    with pytest.raises(MeshError, match="no tetrahedra"):
        mesh_io.read_tet_mesh(path)

    points, tets = box_tet_mesh(1, 1, 1)
    for fmt, binary in (("gmsh22", False), ("gmsh", True)):
        path = tmp_path / f"{fmt}_{binary}.msh"
        meshio.write(str(path), meshio.Mesh(points, [("tetra", tets)]), file_format=fmt,
                     binary=binary)
        parsed = gmsh.parse(path.read_text(errors="replace"))
        assert parsed is None if binary else parsed.tetrahedra() is None
        p, t = mesh_io.read_tet_mesh(path)
        assert np.array_equal(p, points) and np.array_equal(t, tets)


def test_parametric_nodes_are_left_to_meshio():
    text = _msh41([1, 2, 3, 4], UNIT_TET, [(1, 2, 3, 4)], parametric="1")
    assert gmsh.parse(text).points is None and gmsh.parse(text).tetrahedra() is None


def test_a_short_coordinate_line_is_not_guessed_at(tmp_path):
    """A node line with two numbers: no reading of it here; meshio's error names it."""
    text = _msh41([1, 2, 3, 4], UNIT_TET, [(1, 2, 3, 4)]).replace("0.0 0.0 1.0", "0.0 1.0")
    assert gmsh.parse(text) is None
    path = tmp_path / "short.msh"
    path.write_text(text)
    with pytest.raises(MeshError, match="short.msh"):
        mesh_io.read_tet_mesh(path)


def test_reading_the_originals_format_does_not_import_meshio(tmp_path):
    points, tets = box_tet_mesh(2, 2, 2)
    path = write_msh(tmp_path / "box.msh", points, tets)
    code = ("import sys; from ipcsim.model.mesh_io import read_tet_mesh; "
            f"p, t = read_tet_mesh({str(path)!r}); "
            "print(len(p), len(t), 'meshio' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == [str(len(points)), str(len(tets)), "False"]
