"""build_model: placement, rotateModel/size, masses, materials, BC selection, parameters."""

from __future__ import annotations

import math

from msgspec.structs import replace
import numpy as np
import pytest

from ipcsim.errors import MeshError, SceneError
from ipcsim.model.build import build_model
from ipcsim.model.builder import place, voronoi_triangle_masses
from ipcsim.model.generate import box_tet_mesh
from ipcsim.model.kinematics import rotation_xyz
from ipcsim.model.model import Model
from ipcsim.model.surface import boundary_triangles
from ipcsim.scene.spec import (DirichletSpec, InitialVelocitySpec, MaterialSpec,
                               MeshObstacleSpec, NeumannSpec, PlaneSpec, SceneSpec, ShapeSpec)

INF = math.inf


def _cube_corner(model: Model, shape: int, corner) -> np.ndarray:
    """Rest position of the vertex of `shape` that sits at `corner` of the unit file cube."""
    sl = model.shape_vertices(shape)
    return sl.start + int(np.flatnonzero(np.all(np.isclose(FILE_CUBE, corner), axis=1))[0])


FILE_CUBE = np.array([[i, j, k] for k in (0, 1) for j in (0, 1) for i in (0, 1)], dtype=float)


# ----------------------------------------------------------------------------- placement


def test_rotation_order_and_placement_by_hand():
    # Rz(90) maps x to y; Rx(90) maps y to z: R = Rx Ry Rz applies Rz first
    assert np.allclose(rotation_xyz(np.radians([0, 0, 90])) @ [1, 0, 0], [0, 1, 0])
    assert np.allclose(rotation_xyz(np.radians([90, 0, 90])) @ [1, 0, 0], [0, 0, 1])
    assert np.allclose(rotation_xyz(np.radians([0, 90, 0])) @ [1, 0, 0], [0, 0, -1])
    # scale, then rotate, then translate: (1,1,1) -> (2,3,4) -> (-3,2,4) -> (-2,4,7)
    p = place(np.array([[1.0, 1.0, 1.0]]), (1, 2, 3), (0, 0, 90), (2, 3, 4))
    assert np.allclose(p, [[-2, 4, 7]])
    # (1,0,0) -Rz(90)-> (0,1,0) -Ry(90)-> (0,1,0) -Rx(90)-> (0,0,1)
    assert np.allclose(place(np.array([[1.0, 0, 0]]), (0, 0, 0), (90, 90, 90), (1, 1, 1)),
                       [[0, 0, 1]])


def test_shape_placement_in_model(mesh_dir):
    spec = ShapeSpec(mesh_dir / "cube1.msh", translation=(1, 2, 3), rotation_deg=(0, 0, 90),
                     scale=(2, 3, 4))
    model = build_model(SceneSpec(shapes=(spec,)))
    i = _cube_corner(model, 0, (1, 1, 1))
    assert np.allclose(model.rest_positions[i], [-2, 4, 7])
    assert np.array_equal(model.rest_positions, model.initial_positions)
    assert np.all(model.rest_volumes > 0)
    assert model.rest_volumes.sum() == pytest.approx(24.0)  # 2 * 3 * 4
    # l = rest AABB diagonal: extents (3, 2, 4)
    assert model.bbox_diagonal == pytest.approx(math.sqrt(9 + 4 + 16))


def test_mirroring_scale_keeps_tets_positive(mesh_dir):
    model = build_model(SceneSpec(shapes=(ShapeSpec(mesh_dir / "cube3.msh", scale=(-1, 1, 1)),)))
    assert np.all(model.rest_volumes > 0)
    assert any("mirror" in w for w in model.warnings)
    x = model.rest_positions
    tris = model.surface_triangles
    normals = np.cross(x[tris[:, 1]] - x[tris[:, 0]], x[tris[:, 2]] - x[tris[:, 0]])
    outward = (x[tris].mean(axis=1) - x.mean(axis=0))
    assert np.all(np.einsum("ij,ij->i", normals, outward) > 0)


def test_rotate_model_pivot_quirk_and_size(mesh_dir):
    spec = ShapeSpec(mesh_dir / "cube1.msh", translation=(2, 0, 0))
    scene = SceneSpec(shapes=(spec,), rotate_model=(0, 0, 1, 180))
    model = build_model(scene)
    # pivot = (max - min) / 2 = (0.5, 0.5, 0.5), not the AABB centre (2.5, 0.5, 0.5)
    i = _cube_corner(model, 0, (0, 0, 0))
    assert np.allclose(model.rest_positions[i], [2, 0, 0])  # rest shape is not rotated
    assert np.allclose(model.initial_positions[i], [-1, 1, 0])
    # size: largest extent of the initial AABB becomes `size`, min corner at the origin
    spec = ShapeSpec(mesh_dir / "cube1.msh", translation=(5, 5, 5), scale=(1, 2, 1))
    model = build_model(SceneSpec(shapes=(spec,), size=1.0))
    assert np.allclose(model.initial_positions.min(axis=0), 0)
    assert np.allclose(model.initial_positions.max(axis=0), [0.5, 1.0, 0.5])
    assert np.allclose(model.rest_positions, model.initial_positions)
    assert model.bbox_diagonal == pytest.approx(math.sqrt(1.5))


# ----------------------------------------------------------------------------- materials, masses


def test_masses_lame_and_rest_shape(mesh_dir):
    heavy = MaterialSpec(3000.0, 1e8, 0.3)
    shapes = (ShapeSpec(mesh_dir / "cube3.msh", translation=(0, 3, 0), material=heavy),
              ShapeSpec(mesh_dir / "bar.msh", scale=(0.5, 1, 1)))
    model = build_model(SceneSpec(shapes=shapes))
    m0 = model.mass[model.shape_vertices(0)].sum()
    m1 = model.mass[model.shape_vertices(1)].sum()
    assert m0 == pytest.approx(3000.0 * 1.0)  # rho * volume
    assert m1 == pytest.approx(1000.0 * 2.0)
    assert np.all(model.mass > 0)
    mu, lam = model.lame[model.tet_shape == 0][0]
    assert mu == pytest.approx(1e8 / (2 * 1.3)) and lam == pytest.approx(1e8 * 0.3 / (1.3 * 0.4))
    mu, lam = model.lame[model.tet_shape == 1][0]
    assert mu == pytest.approx(1e5 / 2.8) and lam == pytest.approx(1e5 * 0.4 / (1.4 * 0.2))
    # Dm^-1 inverts the rest edge matrix [x1-x0, x2-x0, x3-x0]
    x = model.rest_positions[model.tets]
    dm = np.stack([x[:, 1] - x[:, 0], x[:, 2] - x[:, 0], x[:, 3] - x[:, 0]], axis=2)
    assert np.allclose(model.Dm_inv @ dm, np.eye(3))
    assert np.allclose(model.rest_volumes, np.linalg.det(dm) / 6)


def test_bad_materials_warn_or_fail(mesh_dir):
    shapes = (ShapeSpec(mesh_dir / "cube1.msh", material=MaterialSpec(-1.0, 1e5, 0.3)),
              ShapeSpec(mesh_dir / "cube1.msh", translation=(3, 0, 0),
                        material=MaterialSpec(math.nan, 1e5, 0.3)))
    model = build_model(SceneSpec(shapes=shapes))
    assert model.mass.sum() == pytest.approx(2000.0)  # both fall back to the global density
    assert len([w for w in model.warnings if "material" in w]) == 2
    bad_nu = (ShapeSpec(mesh_dir / "cube1.msh", material=MaterialSpec(1000.0, 1e5, 0.5), line=4),)
    with pytest.raises(SceneError, match="Poisson") as info:
        build_model(SceneSpec(shapes=bad_nu))
    assert info.value.line == 4


def test_codim_masses(mesh_dir):
    (mesh_dir / "seg.seg").write_text("v 0 0 0\nv 2 0 0\nv 2 1 0\ns 1 2\ns 2 3\n")
    (mesh_dir / "p.pt").write_text("v 0 0 0\nv 1 1 1\n")
    shapes = (ShapeSpec(mesh_dir / "cube3.msh"), ShapeSpec(mesh_dir / "tri.obj"),
              ShapeSpec(mesh_dir / "seg.seg"), ShapeSpec(mesh_dir / "p.pt"))
    model = build_model(SceneSpec(shapes=shapes))
    tet_mean = model.mass[model.shape_vertices(0)].mean()
    assert np.allclose(model.mass[model.shape_vertices(3)], tet_mean)
    seg = model.mass[model.shape_vertices(2)]
    # each end of a segment of length L gets rho pi L^3 / 12
    assert np.allclose(seg, 1000 * math.pi / 12 * np.array([8, 8 + 1, 1]))
    tri = model.mass[model.shape_vertices(1)]
    # right isosceles triangle (legs 1, area 1/2): Voronoi corner areas A/2 at the right
    # angle (vertex 0), A/4 at the others; times rho and mean edge length / 3
    mean_edge = (2 + math.sqrt(2)) / 3
    assert np.allclose(tri, 1000 * np.array([0.25, 0.125, 0.125]) * mean_edge / 3)
    corner = voronoi_triangle_masses(np.array([[0, 0, 0], [1, 0, 0], [0.5, math.sqrt(3) / 2, 0]]),
                                     np.array([[0, 1, 2]]), 1.0)
    # equilateral: each corner gets a third of the area, times edge / 3
    assert np.allclose(corner, math.sqrt(3) / 4 / 3 / 3)
    assert np.all(model.always_kinematic[model.shape_vertices(1).start:])
    assert not model.always_kinematic[model.shape_vertices(0)].any()


# ----------------------------------------------------------------------------- collision mesh


def test_collision_mesh_and_planes(mesh_dir):
    (mesh_dir / "p.pt").write_text("v 5 5 5\n")
    shapes = (ShapeSpec(mesh_dir / "cube3.msh"), ShapeSpec(mesh_dir / "tri.obj"),
              ShapeSpec(mesh_dir / "tri.seg"), ShapeSpec(mesh_dir / "p.pt"))
    planes = (PlaneSpec("ground", (0, 0, 0), (0, 1, 0), 0.2),
              PlaneSpec("halfSpace", (0, 1.13, 0), (1, 2, 0), 0.0, 50.0))
    model = build_model(SceneSpec(shapes=shapes, planes=planes))
    n_cube_tris = 4 * 27
    assert len(model.surface_triangles) == n_cube_tris + 1
    assert np.array_equal(np.bincount(model.triangle_shape), [n_cube_tris, 1])
    assert np.array_equal(np.bincount(model.edge_shape), [n_cube_tris * 3 // 2, 3, 3])
    # collision vertices: the 3x3x3-cell cube has 64 vertices, 8 of them interior
    assert len(model.surface_vertices) == (64 - 8) + 3 + 3 + 1
    assert np.all(np.diff(model.surface_vertices) > 0)
    assert np.allclose(model.plane_normals[1], np.array([1, 2, 0]) / math.sqrt(5))
    assert model.plane_friction.tolist() == [0.2, 0.0]


def test_mesh_obstacle_placement(mesh_dir):
    points, tets = box_tet_mesh(1, 1, 1)  # a closed unit-cube surface as an .obj
    obj = mesh_dir / "box.obj"
    obj.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in points)
                   + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in boundary_triangles(tets)))
    ob = MeshObstacleSpec(obj, position=(1, -2, 3), size=4.0, rotation_deg=(0, 45, 0))
    scene = SceneSpec(shapes=(ShapeSpec(mesh_dir / "cube1.msh"),), mesh_obstacles=(ob,),
                      size=2.0)
    model = build_model(scene)
    assert model.shape_kinds == ("tet", "obstacle")
    x = model.rest_positions[model.shape_vertices(1)]
    assert np.allclose(x.mean(axis=0), [1, -2, 3])  # vertex average at the position
    assert np.allclose(np.ptp(x, axis=0), [4 * math.sqrt(2), 4, 4 * math.sqrt(2)])
    assert np.all(model.always_kinematic[model.shape_vertices(1)])
    assert len(model.surface_triangles) == 12 + 12
    assert model.needs_mesh_contact
    # l ignores obstacles (and `size` rescaled only the tet shape)
    assert model.bbox_diagonal == pytest.approx(2 * math.sqrt(3))
    no_self = build_model(replace(scene, self_collision=False))
    assert not no_self.needs_self_contact and no_self.needs_mesh_contact


# ----------------------------------------------------------------------------- BC selection


def _brute_force_select(file_points, boundary, box_min, box_max):
    lo, hi = file_points.min(axis=0), file_points.max(axis=0)
    out = []
    for i, x in enumerate(file_points):
        if i not in boundary:
            continue
        if all((hi[a] - lo[a]) * box_min[a] + lo[a] <= x[a] <= (hi[a] - lo[a]) * box_max[a]
               + lo[a] for a in range(3)):
            out.append(i)
    return out


def test_dbc_nbc_selection_by_file_coordinates(mesh_dir):
    """Boxes are relative to the FILE-space AABB; placement does not change the selection."""
    from ipcsim.model.mesh_io import read_tet_mesh

    file_points, tets = read_tet_mesh(mesh_dir / "cube3.msh")
    boundary = set(np.unique(boundary_triangles(tets)).tolist())
    boxes = [((-0.1, -0.1, -0.1), (0.1, 1.1, 0.1)), ((0.9, -0.1, 0.9), (1.1, 1.1, 1.1)),
             ((0.3, 0.3, 0.3), (0.7, 0.7, 0.7)), ((0, 0, 0), (1 / 3, 1, 1))]
    dbc = tuple(DirichletSpec(lo, hi, (0.1, 0, 0)) for lo, hi in boxes)
    nbc = tuple(NeumannSpec(lo, hi, (0, 0, 1)) for lo, hi in boxes)
    spec = ShapeSpec(mesh_dir / "cube3.msh", translation=(0, 1, 0), rotation_deg=(30, 0, 60),
                     scale=(2, 1, 3), dbc=dbc, nbc=nbc)
    first = ShapeSpec(mesh_dir / "cube1.msh", translation=(5, 0, 0))
    model = build_model(SceneSpec(shapes=(first, spec)))
    off = model.shape_offsets[1]
    expected = [_brute_force_select(file_points, boundary, lo, hi) for lo, hi in boxes]
    # the middle box holds only interior vertices: no BC, a warning
    assert expected[2] == []
    assert sum("selects no boundary vertex" in w for w in model.warnings) == 2
    non_empty = [e for e in expected if e]
    assert [s.vertices.tolist() for s in model.dbc_sets] == [[off + i for i in e] for e in non_empty]
    assert [s.vertices.tolist() for s in model.nbc_sets] == [[off + i for i in e] for e in non_empty]
    assert len(expected[3]) == 2 * 16 - 4  # two layers of x (0, 1/3) on the boundary, inclusive
    assert all(s.gated for s in model.dbc_sets)


def test_tutorial_dbc_selection(ipc_examples):
    """2cubesFall_DBC.txt: two DBC boxes on the lower cube, checked by brute force."""
    from ipcsim.model.mesh_io import read_tet_mesh

    cube = ipc_examples / "input/tetMeshes/cube.msh"
    d1 = DirichletSpec((-0.1, -0.1, -0.1), (0.1, 1.1, 0.1), (-0.2, 0, -0.2))
    d2 = DirichletSpec((0.9, -0.1, 0.9), (1.1, 1.1, 1.1), (0.2, 0, 0.2))
    scene = SceneSpec(shapes=(ShapeSpec(cube, translation=(0, 3, 0)),
                              ShapeSpec(cube, translation=(0, 1, 0), dbc=(d1, d2))),
                      planes=(PlaneSpec("ground", (0, 0, 0), (0, 1, 0), 0.1),),
                      self_friction=0.1)
    model = build_model(scene)
    pts, tets = read_tet_mesh(cube)
    boundary = set(np.unique(boundary_triangles(tets)).tolist())
    for s, d in zip(model.dbc_sets, (d1, d2)):
        want = [8 + i for i in _brute_force_select(pts, boundary, d.box_min, d.box_max)]
        assert s.vertices.tolist() == want and len(want) == 2
        assert s.linear_velocity == d.linear_velocity
    assert "friction (mu=0.1 mesh contacts, ground 0.1)" in model.terms
    assert "Dirichlet BC (2 moving sets)" in model.terms


# ----------------------------------------------------------------------------- initial state


def test_init_velocity(mesh_dir):
    iv = InitialVelocitySpec((0, -20, 0), (0, 0, 90))
    d = DirichletSpec((-0.1, -0.1, -0.1), (0.1, 0.1, 0.1))
    shapes = (ShapeSpec(mesh_dir / "cube1.msh", translation=(0, 3, 0), init_velocity=iv, dbc=(d,)),
              ShapeSpec(mesh_dir / "cube1.msh"))
    model = build_model(SceneSpec(shapes=shapes))
    v = model.initial_velocities
    i = _cube_corner(model, 0, (1, 1, 1))  # r = x - c = (0.5, 0.5, 0.5), w = (0, 0, pi/2)
    assert np.allclose(v[i], [-math.pi / 4, -20 + math.pi / 4, 0])
    fixed = _cube_corner(model, 0, (0, 0, 0))  # a DBC vertex gets no initial velocity
    assert np.allclose(v[fixed], 0)
    assert np.allclose(v[model.shape_vertices(1)], 0)
    # a legacy script ignores initVel (with a warning)
    model = build_model(SceneSpec(shapes=shapes, script="fallNoShift"))
    assert np.allclose(model.initial_velocities, 0)
    assert any("initVel" in w for w in model.warnings)


def test_restart_sets_initial_state(mesh_dir, tmp_path):
    scene = SceneSpec(shapes=(ShapeSpec(mesh_dir / "cube1.msh"),))
    pos = FILE_CUBE + [0, 2, 0]
    vel = np.tile([0.0, -1.0, 0.5], (8, 1))
    lines = ["timestep 7", "", "position 8 3", *[" ".join(f"{v:.20g}" for v in r) for r in pos],
             "", "velocity 24", *(f"{v:.20g}" for v in vel.ravel())]
    status = tmp_path / "status7"
    status.write_text("\n".join(lines) + "\n")
    model = build_model(replace(scene, restart=status))
    assert np.allclose(model.initial_positions, pos)  # cube1 vertices are in FILE_CUBE order
    assert np.allclose(model.initial_velocities, vel)
    status.write_text("\n".join(lines).replace("position 8 3", "position 7 3") + "\n")
    with pytest.raises((SceneError, MeshError)):
        build_model(replace(scene, restart=status))


# ----------------------------------------------------------------------------- parameters, terms


def test_absolute_parameters(mesh_dir):
    base = SceneSpec(shapes=(ShapeSpec(mesh_dir / "cube1.msh", scale=(3, 4, 12)),),
                     dt=0.01, newton_tol=(1e-3, 1e-2), dhat=2e-3, epsv=1e-4, dtol=1e-8)
    model = build_model(base)
    l = 13.0
    assert model.bbox_diagonal == pytest.approx(l)
    assert model.dhat == pytest.approx(2e-3 * l)
    assert model.epsv == pytest.approx(1e-4 * l) and model.dtol == pytest.approx(1e-8 * l)
    assert model.newton_tol(0) == pytest.approx(1e-3 * l * 0.01)
    assert model.newton_tol(5) == pytest.approx(1e-2 * l * 0.01)
    assert model.kappa is None
    ab = build_model(replace(base, use_abs_parameters=True, kappa=1e5))
    assert ab.dhat == 2e-3 and ab.epsv == 1e-4 and ab.dtol == 1e-8
    assert ab.newton_tol(0) == 1e-3 and ab.kappa == 1e5
    given = build_model(replace(base, dhat_abs=0.05, epsv_abs=0.2, dhat_start=4e-3))
    assert given.dhat == 0.05 and given.epsv == 0.2
    damped = build_model(replace(base, damping_ratio=0.5))
    assert damped.damping_stiffness == pytest.approx(0.75 * 0.5 * 0.01**3)


def test_terms_only_what_the_scene_needs(mesh_dir):
    cube = mesh_dir / "cube1.msh"
    plain = SceneSpec(shapes=(ShapeSpec(cube),), gravity=False, self_collision=False)
    model = build_model(plain)
    assert model.terms == ("inertia (backward Euler)", "elasticity: neo-Hookean (1 shape)")
    assert not model.needs_mesh_contact and not model.needs_friction
    full = replace(
        plain, gravity=True, self_collision=True, self_friction=0.0, energy="FCR",
        planes=(PlaneSpec("ground", (0, 0, 0), (0, 1, 0), 0.0),), damping_stiff=0.1,
        shapes=(ShapeSpec(cube, translation=(0, 2, 0),
                          nbc=(NeumannSpec((0, 0, 0), (1, 1, 1), (1, 0, 0)),)),
                ShapeSpec(cube, linear_velocity=(0, 0, 0))))
    model = build_model(full)
    assert model.terms == ("inertia (backward Euler)", "gravity",
                           "elasticity: fixed corotated (1 shape)", "damping (stiffness 0.1)",
                           "plane contact (1 plane)", "mesh contact (self collision on)",
                           "Neumann BC (1 set)", "Dirichlet BC (1 fixed set)")
    assert not model.needs_friction  # every mu is 0
    assert model.elastic_tets.tolist() == [True] * 6 + [False] * 6
    fric = build_model(replace(full, self_friction=0.2))
    assert fric.needs_friction and "friction (mu=0.2 mesh contacts)" in fric.terms


def test_model_is_frozen_and_read_only(mesh_dir):
    model = build_model(SceneSpec(shapes=(ShapeSpec(mesh_dir / "cube1.msh"),)))
    with pytest.raises(AttributeError):
        model.dhat = 1.0
    for name in ("rest_positions", "tets", "mass", "surface_triangles", "Dm_inv"):
        arr = getattr(model, name)
        assert not arr.flags.writeable
        with pytest.raises(ValueError):
            arr[0] = 0
    assert model.tets.dtype == np.int64 and model.rest_positions.dtype == np.float64


def test_scene_errors(mesh_dir):
    with pytest.raises(SceneError, match="at least one tetrahedral"):
        build_model(SceneSpec(shapes=(ShapeSpec(mesh_dir / "tri.obj"),)))
    with pytest.raises(MeshError) as info:
        build_model(SceneSpec(shapes=(ShapeSpec(mesh_dir / "missing.msh", line=9),)))
    assert info.value.line == 9 and "missing.msh" in str(info.value)
    with pytest.raises(SceneError, match="scale"):
        build_model(SceneSpec(shapes=(ShapeSpec(mesh_dir / "cube1.msh", scale=(1, 0, 1)),)))
    with pytest.raises(SceneError, match="not supported"):
        build_model(SceneSpec(shapes=(ShapeSpec(mesh_dir / "cube1.msh"),), script="hang"))
