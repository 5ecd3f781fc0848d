"""Build the model of every example script of the original, and of the project's own
scenes, and check the counts are sane. Needs the scene readers (skips without them)."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from examples import example_scripts, extra_scripts_with_meshes
from ipcsim.model.build import build_model
from ipcsim.model.kinematics import kinematic_targets, nbc_accelerations
from ipcsim.model.mesh_io import read_shape
from ipcsim.model.surface import edge_use_counts

scene_pkg = pytest.importorskip("ipcsim.scene")
if not hasattr(scene_pkg, "load_scene"):
    pytest.skip("the scene readers (ipcsim.scene.load_scene) are not written yet",
                allow_module_level=True)
load_scene = scene_pkg.load_scene

# the curated set, and the scripts only the full example tree has (those whose meshes exist)
SCRIPTS = [p for p in example_scripts() + extra_scripts_with_meshes()
           if "segMeshes" not in p.parts]


def _check_model(model, scene):
    n = model.n_vertices
    # vertex counts: every shape's file vertices, in scene order
    for i, spec in enumerate(scene.shapes):
        data = read_shape(spec.mesh_path, spec.kind, spec.line)
        assert model.shape_offsets[i + 1] - model.shape_offsets[i] == len(data["points"])
    assert model.tets.min() >= 0 and model.tets.max() < n
    assert np.all(model.rest_volumes > 0) and np.all(model.mass > 0)
    assert np.isfinite(model.initial_positions).all()
    # each tet shape's boundary is closed
    for s in range(model.n_shapes):
        if model.shape_kinds[s] == "tet":
            tris = model.surface_triangles[model.triangle_shape == s]
            assert np.all(edge_use_counts(tris)[1] == 2)
    # tet masses sum to rho * volume per shape
    tet_v = np.zeros(n, dtype=bool)
    tet_v[model.tets.ravel()] = True
    rho = {i: (s.material.density if s.material else scene.density)
           for i, s in enumerate(scene.shapes)}
    for s in range(model.n_scene_shapes):
        if model.shape_kinds[s] == "tet":
            sl = model.shape_vertices(s)
            want = rho[s] * model.rest_volumes[model.tet_shape == s].sum()
            assert model.mass[sl].sum() == pytest.approx(want)
    assert model.bbox_diagonal > 0 and model.dhat > 0
    if not scene.use_abs_parameters and scene.dhat_abs is None:
        assert model.dhat == pytest.approx(scene.dhat * model.bbox_diagonal)
    for s in model.dbc_sets:
        assert len(s.vertices) and s.vertices.max() < n
    mask, targets = kinematic_targets(model, model.initial_positions, 0.0, scene.dt)
    assert mask.shape == (n,) and np.isfinite(targets).all()
    assert np.isfinite(nbc_accelerations(model, 0.0)).all()
    for seq in model.mesh_sequences:  # every step of the run has its frame
        assert seq.frame_path(scene.n_steps - 1).with_suffix(".seg").exists() or \
            seq.frame_path(scene.n_steps - 1).with_suffix(".obj").exists()
    assert model.terms[0].startswith("inertia")


@pytest.mark.skipif(not SCRIPTS, reason="../shared/ipc-examples is not present")
@pytest.mark.parametrize("path", SCRIPTS, ids=lambda p: p.stem)
def test_example_model(path):
    scene = load_scene(path)
    model = build_model(scene)
    _check_model(model, scene)
    script = scene.script
    codim = [i for i, k in enumerate(model.shape_kinds) if k not in ("tet", "obstacle")]
    if script == "twist":
        assert len(model.dbc_sets) == 2 and all(s.moving for s in model.dbc_sets)
    elif script == "DCOFix":
        assert len(model.dbc_sets) == len(codim)
    elif script == "pushRightMost1":
        assert [len(s.vertices) for s in model.dbc_sets] == [1]
    elif script == "fall" and not (scene.rotate_model and scene.rotate_model[3]):
        # the scene's own shapes are lifted, meshCO obstacles are not
        own = model.shape_offsets[model.n_scene_shapes]
        shift = model.initial_positions - model.rest_positions
        assert np.allclose(shift[:, [0, 2]], 0) and np.all(shift[:own, 1] > 0)
        assert not shift[own:].any()
    elif script == "null":
        assert np.all(model.always_kinematic[np.isin(model.vertex_shape, codim)])
    elif script == "hangLeft":
        assert len(model.dbc_sets) == 1 and not model.dbc_sets[0].moving
    elif script == "dragright":
        (s,) = model.dbc_sets
        assert s.release is not None and s.linear_velocity == (0.5, 0.0, 0.0)
        assert model.kinematic_mask_at(0.0)[s.vertices].all()  # still left of the funnel
    elif script in ("stretchAndPause", "DCOSqueezeOut", "DCOSegBedSquash", "DCOSquash6"):
        # switching motion: moving sets whose windows end, followed by their next run
        moving = [s for s in model.dbc_sets if s.moving]
        assert moving and all(s.time_range[1] < math.inf or s.time_range[0] > 0
                              for s in moving)
        if script != "stretchAndPause":  # codim shapes fixed, as DCOFix
            fixed = {int(model.vertex_shape[s.vertices[0]]) for s in model.dbc_sets}
            assert set(codim) <= fixed


@pytest.mark.skipif(not SCRIPTS, reason="../shared/ipc-examples is not present")
def test_tutorial_details(ipc_examples):
    tut = ipc_examples / "input/tutorialExamples"
    model = build_model(load_scene(tut / "BC/2cubesFall_DBC_timeRange.txt"))
    assert [len(s.vertices) for s in model.dbc_sets] == [2, 2, 2, 2]
    assert [s.time_range for s in model.dbc_sets] == [(0.0, 2.5), (2.5, math.inf),
                                                       (0.0, 2.5), (2.5, math.inf)]
    model = build_model(load_scene(tut / "initVel/2cubesFall_initVel.txt"))
    assert np.allclose(model.initial_velocities[:8], [0, -20, 0])
    assert np.allclose(model.initial_velocities[8:], 0)
    model = build_model(load_scene(tut / "MCO/2cubesFall_rotateCO_edges.txt"))
    assert model.shape_kinds == ("tet", "segments") and len(model.surface_edges) == 18 + 3


def test_project_scenes(repo_root):
    scenes = sorted(repo_root.joinpath("input").glob("*.txt"))
    scenes += sorted(repo_root.joinpath("input").glob("*.toml"))
    assert any(p.name == "two_cubes_fall.txt" for p in scenes)
    for path in scenes:
        scene = load_scene(path)
        model = build_model(scene)
        if scene.dimension == 2:  # its triangles and masses (tests/model/test_builder_2d.py)
            assert np.all(model.tri_rest_areas > 0) and np.all(model.mass > 0)
            continue
        _check_model(model, scene)
    model = build_model(load_scene(repo_root / "input/two_cubes_fall.txt"))
    assert model.n_tets == 2 * 750 and model.n_vertices == 2 * 216
    assert "friction (mu=0.1 mesh contacts, ground 0.1)" in model.terms
    assert model.needs_mesh_contact and model.needs_friction


def test_check_command(repo_root, capsys):
    from ipcsim.cli import main

    assert main(["check", str(repo_root / "input/two_cubes_fall.txt")]) == 0
    out = capsys.readouterr().out
    assert "elasticity: neo-Hookean (2 shapes)" in out
    assert re.search(r"^\s+tets\s+1500$", out, re.M) and re.search(r"^\s+steps\s+200$", out, re.M)
