"""The Model of a 2D scene (model/builder_2d.py) and the readers of its meshes: positions in
the plane z = 0, triangles with their rest shapes, springs, masses (lumped and the
lecture's uniform ones), the boundary edges that collide and their contact lengths,
placement, boundary conditions, moving planes; and the lecture's own set-up of lessons 3
and 7 where ../shared/solid-sim-tutorial is there."""

from __future__ import annotations

import numpy as np
import pytest

from ipcsim.errors import MeshError
from ipcsim.model import mesh_io
from ipcsim.model.build import build_model
from ipcsim.model.builder_2d import build_model_2d
from ipcsim.model.generate import rectangle_mesh, write_msh
from ipcsim.scene import load_scene

HEAD = "[scene]\ndimension = 2\n"


def square(resolution=4, extra="", shape_extra="", size=1.0):
    return (HEAD + extra + f'[[shapes]]\nkind = "rectangle"\nsize = [{size}, {size}]\n'
            f"resolution = [{resolution}, {resolution}]\n" + shape_extra)


@pytest.fixture
def build(tmp_path):
    def build_text(text: str):
        path = tmp_path / "scene.toml"
        path.write_text(text)
        return build_model_2d(load_scene(path))
    return build_text


def test_a_rectangle_is_a_body_in_the_plane(build):
    m = build(square(extra="[material]\ndensity = 500\nyoungs_modulus = 2e5\n"
                           "poisson_ratio = 0.25\n"))
    assert m.dimension == 2 and m.n_vertices == 25 and m.n_tets == 0
    assert np.all(m.rest_positions[:, 2] == 0.0) and np.all(m.initial_positions[:, 2] == 0.0)
    np.testing.assert_allclose(m.rest_positions.min(0)[:2], [-0.5, -0.5])
    assert m.tri_elements.shape == (32, 3) and np.all(m.elastic_tri_elements)
    np.testing.assert_allclose(m.tri_rest_areas, 1.0 / 32)
    # at rest F = Ds Dm⁻¹ = I
    x = m.rest_positions
    t = m.tri_elements
    Ds = np.stack([x[t[:, 1], :2] - x[t[:, 0], :2], x[t[:, 2], :2] - x[t[:, 0], :2]], axis=2)
    np.testing.assert_allclose(Ds @ m.tri_Dm_inv, np.broadcast_to(np.eye(2), Ds.shape),
                               atol=1e-14)
    mu, lam = 2e5 / 2.5, 2e5 * 0.25 / (1.25 * 0.5)
    np.testing.assert_allclose(m.tri_lame, np.broadcast_to([mu, lam], (32, 2)))
    # lumped: ρ A / 3 per corner, the body's mass in all
    assert m.mass.sum() == pytest.approx(500.0)
    corner = np.bincount(t.ravel(), weights=np.full(96, 500.0 / 96), minlength=25)
    np.testing.assert_allclose(m.mass, corner)
    assert m.springs.shape == (0, 2) and m.contact_barrier == "ipc"


def test_boundary_edges_face_outward_and_give_each_vertex_half_of_their_length(build):
    m = build(square(resolution=3, size=1.5))
    e = m.surface_edges
    assert len(e) == 12 and len(m.surface_triangles) == 0
    assert m.surface_vertices.tolist() == sorted(set(e.ravel().tolist()))
    x = m.rest_positions
    d = x[e[:, 1]] - x[e[:, 0]]
    normal = np.column_stack([d[:, 1], -d[:, 0]])  # right of the edge
    mid = 0.5 * (x[e[:, 0]] + x[e[:, 1]])
    assert np.all(np.einsum("ij,ij->i", normal, mid[:, :2]) > 0)  # away from the centre
    boundary = np.zeros(len(x), bool)
    boundary[e.ravel()] = True
    np.testing.assert_allclose(m.node_contact_length[boundary], 0.5)  # L / n
    assert np.all(m.node_contact_length[~boundary] == 0.0)


def test_springs_and_the_lectures_conventions(build):
    m = build(square(extra='[material]\nnode_masses = "uniform"\n[contact]\n'
                           'barrier = "lecture"\n', shape_extra="spring_stiffness = 2e4\n"))
    assert m.springs.shape == (4 * 5 * 2 + 2 * 16, 2)  # cell sides, both cell diagonals
    assert np.all(m.spring_stiffness == 2e4) and np.all(m.elastic_springs)
    d = m.rest_positions[m.springs[:, 0]] - m.rest_positions[m.springs[:, 1]]
    np.testing.assert_allclose(m.spring_rest_length_sq, np.sum(d * d, axis=1))
    assert set(np.round(m.spring_rest_length_sq, 12)) == {0.0625, 0.125}
    assert not np.any(m.elastic_tri_elements)  # the cells carry the mass, not elasticity
    np.testing.assert_allclose(m.mass, 1000.0 / 25)  # ρ side² / (n + 1)², the lecture's
    assert m.contact_barrier == "lecture"
    assert any("mass-spring" in t for t in m.terms) and any("uniform" in t for t in m.terms)


def test_placement_motion_and_planes(build):
    text = square(resolution=2, extra="gravity_acceleration = [0.0, -9.81]\n",
                  shape_extra="translation = [3.0, 1.0]\nrotation_deg = 90\n"
                              "scale = [2.0, 1.0]\n"
                              "init_velocity = { linear = [1.0, 0.0], angular_deg = 0 }\n"
                              "[[shapes.dbc]]\nbox_min = [0.0, 0.99]\nbox_max = [1.0, 1.0]\n"
                              "linear_velocity = [0.0, -0.5]\n"
                              "[[shapes.nbc]]\nbox_min = [0.0, 0.0]\nbox_max = [0.01, 1.0]\n"
                              "acceleration = [0.0, 2.0]\n")
    text += ('[[planes]]\nkind = "ground"\nheight = -1\n[[planes]]\nkind = "halfSpace"\n'
             'origin = [0, 3]\nnormal = [0, -1]\nvelocity = [0, -0.5]\nlimit = [0, 0.5]\n')
    m = build(text)
    x = m.rest_positions
    # file x ∈ [-0.5, 0.5] scaled by 2, turned by 90°: y spans [-1, 1] about 1
    np.testing.assert_allclose(x.min(0), [2.5, 0.0, 0.0], atol=1e-14)
    np.testing.assert_allclose(x.max(0), [3.5, 2.0, 0.0], atol=1e-14)
    assert np.all(m.tri_rest_areas > 0) and m.tri_rest_areas.sum() == pytest.approx(2.0)
    dbc, = m.dbc_sets
    assert dbc.linear_velocity == (0.0, -0.5, 0.0) and len(dbc.vertices) == 3
    assert np.all(m.initial_velocities[dbc.vertices] == 0.0)
    free = np.setdiff1d(np.arange(9), dbc.vertices)
    np.testing.assert_allclose(m.initial_velocities[free], [[1.0, 0.0, 0.0]] * 6)
    assert m.nbc_sets[0].acceleration == (0.0, 2.0, 0.0) and len(m.nbc_sets[0].vertices) == 3
    np.testing.assert_allclose(m.gravity, [0.0, -9.81, 0.0])
    np.testing.assert_allclose(m.plane_normals, [[0, 1, 0], [0, -1, 0]])
    np.testing.assert_allclose(m.plane_velocities, [[0, 0, 0], [0, -0.5, 0]])
    assert np.all(np.isnan(m.plane_limits[0])) and m.plane_limits[1].tolist() == [0, 0.5, 0]


def test_triangle_files_and_kinematic_segments(tmp_path, build):
    points, tris = rectangle_mesh(2, 3, (2.0, 3.0))
    write_msh(tmp_path / "body.msh", points, tris[:, [0, 2, 1]])  # clockwise in the file
    (tmp_path / "wall.seg").write_text("v 0 -1 0\nv 5 -1 0\ns 1 2\n")
    (tmp_path / "body.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    m = build(HEAD + '[[shapes]]\npath = "body.msh"\n[[shapes]]\npath = "wall.seg"\n'
              '[[shapes]]\npath = "body.obj"\ntranslation = [4, 0]\n')
    assert m.shape_kinds == ("triangles", "segments", "triangles")
    assert np.all(m.tri_rest_areas > 0) and len(m.tri_elements) == 13
    assert m.tri_rest_areas[:12].sum() == pytest.approx(6.0)
    wall = np.arange(12, 14)
    assert np.all(m.always_kinematic[wall]) and not m.always_kinematic[:12].any()
    assert m.mass[wall].tolist() == pytest.approx([m.mass[np.r_[:12, 14:17]].mean()] * 2)
    assert [12, 13] in m.surface_edges.tolist()
    assert m.node_contact_length[12] == pytest.approx(2.5)
    assert len(m.dbc_sets) == 1 and m.dbc_sets[0].vertices.tolist() == [12, 13]  # fixed


@pytest.mark.parametrize("content, message", [
    ("v 0 0 0\nv 1 0 0.5\nv 0 1 0\nf 1 2 3\n", "off the plane z = 0"),
    ("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", "zero area"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 1 2 4\n", "triangles overlap"),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 3 2\n", "repeat another one's"),
])
def test_triangle_meshes_that_are_refused(tmp_path, content, message):
    path = tmp_path / "bad.obj"
    path.write_text(content)
    with pytest.raises(MeshError, match=message):
        mesh_io.read_triangle_mesh(path, 7)
    (tmp_path / "tets.msh").write_text("")
    with pytest.raises(MeshError):
        mesh_io.read_triangle_mesh(tmp_path / "tets.msh")


def test_a_tet_mesh_is_not_a_2d_body(tmp_path):
    from ipcsim.model.generate import box_tet_mesh

    write_msh(tmp_path / "cube.msh", *box_tet_mesh(1, 1, 1))
    with pytest.raises(MeshError, match="no triangles in mesh"):
        mesh_io.read_triangle_mesh(tmp_path / "cube.msh")


def test_build_model_builds_a_2d_scene(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(square())
    model = build_model(load_scene(path))
    assert model.dimension == 2 and len(model.tri_elements) == 32


# ----------------------------------------------------------------------------- the lecture


def _tutorial(lesson):
    vt = pytest.importorskip("benchmarks.vs_tutorial")
    if not (vt.TUTORIAL / lesson / "simulator.py").is_file():
        pytest.skip("../shared/solid-sim-tutorial is not present")
    return vt.tutorial_setup(lesson)


def test_lesson_3_set_up_is_the_lectures(build):
    with _tutorial("3_contact") as (ns, _):
        x, e, m, l2 = (np.array(ns[k], dtype=float) for k in ("x", "e", "m", "l2"))
        k, contact = np.array(ns["k"]), np.array(ns["contact_area"])
    model = build(square(extra='[material]\ndensity = 1000\nnode_masses = "uniform"\n',
                         shape_extra="spring_stiffness = 2e4\n"))
    np.testing.assert_allclose(model.rest_positions[:, :2], x, atol=1e-15)
    assert model.springs.tolist() == e.astype(int).tolist()
    np.testing.assert_allclose(model.spring_rest_length_sq, l2, rtol=1e-15)
    np.testing.assert_allclose(model.spring_stiffness, k)
    np.testing.assert_allclose(model.mass, m)
    on_boundary = model.node_contact_length > 0
    np.testing.assert_allclose(model.node_contact_length[on_boundary], contact[on_boundary])


def test_lesson_7_set_up_is_the_lectures(build):
    with _tutorial("7_self_contact") as (ns, _):
        x, tri = np.array(ns["x"], dtype=float), np.array(ns["e"], dtype=int)
        vol, IB = np.array(ns["vol"]), np.array(ns["IB"])
        mu, lam, m = np.array(ns["mu_lame"]), np.array(ns["lam"]), np.array(ns["m"])
        be = {tuple(b) for b in ns["be"]}
    side = 0.45
    text = (HEAD + '[material]\ndensity = 1000\nyoungs_modulus = 1e5\npoisson_ratio = 0.4\n'
            'node_masses = "uniform"\n' + "".join(
                f'[[shapes]]\nkind = "rectangle"\nsize = [{side}, {side}]\nresolution = [2, 2]\n'
                f"translation = [{tx}, {ty}]\n" for tx, ty in ((0, 0), (0.1 * side, -1.1 * side))))
    model = build(text)
    n = model.n_vertices  # the lecture's last node carries its ceiling
    np.testing.assert_allclose(model.rest_positions[:, :2], x[:n], atol=1e-15)
    assert model.tri_elements.tolist() == tri.tolist()
    np.testing.assert_allclose(model.tri_rest_areas, vol, rtol=1e-14)
    np.testing.assert_allclose(model.tri_Dm_inv, IB, rtol=1e-12)
    np.testing.assert_allclose(model.tri_lame, np.column_stack([mu, lam]), rtol=1e-15)
    np.testing.assert_allclose(model.mass, m[:n], rtol=1e-14)
    assert {tuple(b) for b in model.surface_edges.tolist()} == be
