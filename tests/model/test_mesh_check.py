"""The mesh validation every reader runs: each case here used to be accepted (a body with
no surface that fell through the ground, a Gmsh tag 0 read as the last node) or refused
with a message that blamed something else."""

from __future__ import annotations

import meshio
import numpy as np
import pytest

from ipcsim.errors import MeshError
from ipcsim.model import mesh_check, mesh_io
from ipcsim.model.generate import box_tet_mesh, write_msh

POINTS, TETS = box_tet_mesh(2, 2, 2)


def refused(fn, *args, match):
    with pytest.raises(MeshError, match=match) as err:
        fn(*args)
    return err.value


def write_vtu(path, points, tets):
    meshio.write(str(path), meshio.Mesh(points, [("tetra", tets)]))
    return path


def test_a_mesh_listing_every_tet_twice_is_refused(tmp_path):
    """Its boundary extraction found no face used once: 0 surface triangles, a body that
    passed through the ground."""
    path = write_vtu(tmp_path / "twice.vtu", POINTS, np.concatenate([TETS, TETS]))
    err = refused(mesh_io.read_tet_mesh, path, match="repeat another one's four vertices")
    assert "48 tetrahedra" in str(err) and "no surface" in str(err)


def test_a_tet_repeated_with_its_vertices_permuted_is_a_duplicate(tmp_path):
    tets = np.concatenate([TETS, TETS[:1, [1, 2, 0, 3]]])  # an even permutation: positive
    refused(mesh_io.read_tet_mesh, write_vtu(tmp_path / "perm.vtu", POINTS, tets),
            match="1 tetrahedra repeat")


def test_overlapping_tets_are_refused():
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0.1, 0.1, 0.5]], float)
    tets = np.array([[0, 1, 2, 3], [0, 1, 2, 4]])  # both above the shared face
    refused(mesh_check.check_tet_mesh, pts, tets, "m.vtu", 3, match="on the same side")


def test_a_face_in_three_tets_is_refused():
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, -1], [0.2, 0.2, 2]],
                   float)
    tets = np.array([[0, 1, 2, 3], [0, 2, 1, 4], [0, 1, 2, 5]])
    refused(mesh_check.check_tet_mesh, pts, tets, "m.vtu", 3, match="more than two")


def test_an_open_or_inconsistent_boundary_is_refused():
    open_surface = np.array([[0, 1, 2], [0, 2, 3]])
    refused(mesh_check._check_boundary, open_surface, "m.vtu", 3, match="not a closed")
    flipped = np.array([[0, 1, 2], [0, 3, 2], [0, 1, 3], [1, 2, 3]])  # one face reversed
    refused(mesh_check._check_boundary, flipped, "m.vtu", 3, match="consistently oriented")
    refused(mesh_check._check_boundary, np.zeros((0, 3), np.int64), "m.vtu", 3,
            match="no boundary faces")
    tet_faces = np.array([[0, 2, 1], [0, 3, 2], [0, 1, 3], [1, 2, 3]])
    mesh_check._check_boundary(tet_faces, "m.vtu", 3)  # a tet's own surface is closed


def test_huge_coordinates_are_refused_before_any_volume(tmp_path):
    """Coordinates of 1e200 overflowed in the volume check (numpy warnings) and were then
    called 'zero volume'."""
    path = write_vtu(tmp_path / "huge.vtu", POINTS * 1e200, TETS)
    with np.errstate(all="raise"):  # no overflow happens on the way to the message
        err = refused(mesh_io.read_tet_mesh, path, match="beyond 1e\\+09")
    assert "zero volume" not in str(err)


def _msh41_with_tag(tmp_path, tag: int):
    path = write_msh(tmp_path / "box.msh", POINTS, TETS)
    lines = path.read_text().split("\n")
    first = lines.index("$Elements") + 3  # header, block header, first element
    row = lines[first].split()
    row[1] = str(tag)
    lines[first] = " ".join(row)
    bad = tmp_path / f"tag{tag}.msh"
    bad.write_text("\n".join(lines))
    return bad


@pytest.mark.parametrize("tag", [0, -5, 10_000])
def test_a_gmsh_node_tag_that_is_no_node_is_refused(tmp_path, tag):
    """Tag 0 was read as the last node (-1 in Python), a negative tag as some node counted
    from the end, a tag past the last as an IndexError about an axis."""
    err = refused(mesh_io.read_tet_mesh, _msh41_with_tag(tmp_path, tag), 7,
                  match=f"names node tag {tag}, which is not a node")
    assert err.line == 7


def test_gmsh22_tags_are_checked_too(tmp_path):
    path = tmp_path / "box22.msh"
    meshio.write(str(path), meshio.Mesh(POINTS, [("tetra", TETS)]), file_format="gmsh22",
                 binary=False)
    mesh_io.read_tet_mesh(path)  # a good file passes
    text = path.read_text()
    start = text.index("$Elements\n")
    body = text[start:].split("\n")
    row = body[2].split()  # tag type ntags tags... nodes...
    row[-1] = "0"
    body[2] = " ".join(row)
    path.write_text(text[:start] + "\n".join(body))
    refused(mesh_io.read_tet_mesh, path, match="names node tag 0")


def test_a_binary_gmsh_file_is_read_by_meshio_alone(tmp_path):
    path = tmp_path / "bin.msh"
    meshio.write(str(path), meshio.Mesh(POINTS, [("tetra", TETS)]), file_format="gmsh",
                 binary=True)
    points, tets = mesh_io.read_tet_mesh(path)
    assert np.array_equal(tets, TETS)


def test_obj_relative_face_indices_count_back_from_the_last_vertex_so_far(tmp_path):
    """`f -3 -2 -1` is valid OBJ; it was refused as 'outside 1..n'."""
    path = tmp_path / "rel.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 0 0 1\nf 1 2 -1\n"
                    "f -2/1/1 -1//2 1\n")
    points, triangles = mesh_io.read_obj(path)
    assert len(points) == 4
    assert triangles.tolist() == [[0, 1, 2], [0, 1, 3], [2, 3, 0]]


def test_obj_index_zero_is_refused(tmp_path):
    path = tmp_path / "zero.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 -1 -2\n")
    refused(mesh_io.read_obj, path, match="face index 0")


@pytest.mark.parametrize("step", ["inf", "nan", "-3", "2.5", "1e300"])
def test_a_restart_timestep_that_is_no_step_number_is_refused(tmp_path, step):
    """`timestep inf` raised OverflowError (a traceback)."""
    path = tmp_path / "status1"
    path.write_text(f"timestep {step}\n\nposition 1 3\n0 0 0\n\nvelocity 3\n0\n0\n0\n")
    refused(mesh_io.read_status, path, match="not a step number|malformed")


def test_restart_velocities_are_not_bounded_like_coordinates(tmp_path):
    path = tmp_path / "status2"
    path.write_text("timestep 2\n\nposition 1 3\n0 0 0\n\nvelocity 3\n1e12\n0\n0\n")
    step, x, v = mesh_io.read_status(path)
    assert step == 2 and v[0, 0] == 1e12


def test_a_tetgen_header_with_a_negative_count_is_refused(tmp_path):
    (tmp_path / "tg.node").write_text("-4 3 0 0\n")
    (tmp_path / "tg.ele").write_text("1 4 0\n0 0 1 2 3\n")
    refused(mesh_io.read_tet_mesh, tmp_path / "tg.ele", match="bad .node header")
