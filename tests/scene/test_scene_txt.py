"""The original's text format: what each keyword means once read."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from ipcsim.scene import load_scene, parse_txt
from ipcsim.scene.spec import SceneSpec

CUBE = "shapes input 1\nmeshes/cube.msh 0 0 0  0 0 0  1 1 1\n"
DEFAULT = SceneSpec()


def test_defaults_when_only_shapes(load_text, scene_dir):
    s = load_text(CUBE)
    assert (s.duration, s.dt, s.density, s.youngs_modulus, s.poisson_ratio) == (
        5.0, 0.025, 1000.0, 1e5, 0.4)
    assert s.kappa is None and s.dhat == 1e-3 and s.dhat_start is None and s.epsv == 1e-3
    assert s.newton_tol == (1e-2,) and s.gravity and s.self_collision
    sh = s.shapes[0]
    assert sh.mesh_path == scene_dir / "meshes/cube.msh" and sh.path == "meshes/cube.msh"
    assert sh.line == 2 and sh.kind == "tet"
    assert s.warnings == () and s.ignored == ()


def test_comments_blank_lines_crlf_and_trailing_whitespace(load_text):
    text = ("# header\r\n\r\n  time 3 0.01   # trailing comment\r\n"
            "selfFric 0.2 \t \r\n" + CUBE.replace("\n", " \r\n"))
    s = load_text(text)
    assert (s.duration, s.dt, s.self_friction) == (3.0, 0.01, 0.2)
    assert s.shapes[0].line == 6


def test_later_keywords_overwrite_and_obstacles_accumulate(load_text):
    s = load_text("time 4 0.01\ntime 2\nground 0.1 0\nground 0.2 -1\n"
                  "selfCollisionOff\nselfCollisionOn\n" + CUBE + CUBE)
    # `time 2` sets only the duration: dt keeps the previous value
    assert (s.duration, s.dt) == (2.0, 0.01)
    assert [p.friction for p in s.planes] == [0.1, 0.2]
    assert s.planes[1].origin == (0.0, -1.0, 0.0) and s.planes[1].normal == (0.0, 1.0, 0.0)
    assert s.self_collision and len(s.shapes) == 2


def test_tol_reads_following_lines_with_any_whitespace(load_text):
    s = load_text("tol 4\n1e-2 2e-2\n\n# a comment between values\n3e-2\n   4e-2  # last\n"
                  + CUBE)
    assert s.newton_tol == (1e-2, 2e-2, 3e-2, 4e-2)
    assert s.newton_tol_at(0) == 1e-2 and s.newton_tol_at(100) == 4e-2


def test_tuning_maps_onto_kappa_dhat_dtol_epsv(load_text):
    s = load_text("tuning 6\n1e4\n1e-2\n1e-3\n1e-8\n1e-4\n1e-4\n" + CUBE)
    assert (s.kappa, s.dhat_start, s.dhat, s.dtol, s.epsv) == (1e4, 1e-2, 1e-3, 1e-8, 1e-4)
    # kappa 0 means adaptive; equal start/target means no homotopy
    s = load_text("tuning 3\n0\n5e-3\n5e-3\n" + CUBE)
    assert s.kappa is None and s.dhat == 5e-3 and s.dhat_start is None
    assert s.dtol == 1e-9 and s.epsv == 1e-3  # missing entries: built-in values


def test_short_tuning_replaces_the_whole_vector(load_text):
    # the vector is replaced: a dHat given before a short `tuning` is lost
    s = load_text("dHat 1e-4\nepsv 1e-5\ntuning 1\n0\n" + CUBE)
    assert (s.dhat, s.epsv) == (1e-3, 1e-3)
    # dHat after tuning writes both dHat entries (start and target): no homotopy left
    s = load_text("tuning 3\n0\n1e-2\n1e-3\ndHat 2e-3\n" + CUBE)
    assert s.dhat == 2e-3 and s.dhat_start is None


def test_epsv_start_differing_from_target_warns(load_text):
    s = load_text("tuning 6\n0\n1e-3\n1e-3\n1e-9\n1e-2\n1e-3\n" + CUBE)
    assert s.epsv == 1e-3
    assert any(":6: warning:" in w and "target" in w for w in s.warnings)


def test_absolute_extensions(load_text):
    s = load_text("kappa 1e6\ndHatAbs 1e-4\nepsvAbs 2e-3\n" + CUBE)
    assert (s.kappa, s.dhat_abs, s.epsv_abs) == (1e6, 1e-4, 2e-3)
    assert (s.dhat, s.epsv) == (1e-3, 1e-3)  # relative values untouched


def test_sections_follow_the_interior_point_solver(load_text):
    text = ("section QP SQP\ntime 9 0.5\nsection end\n"
            "section interiorPoint\ntime 3 0.01\nsection end\n"
            "section IP\nselfFric 0.3\nsection end\n"
            "section\ndensity 5\nsection end\n" + CUBE)
    s = load_text(text)
    assert (s.duration, s.dt, s.self_friction, s.density) == (3.0, 0.01, 0.3, 1000.0)
    assert s.warnings == ()


def test_sections_follow_the_solver_selected_before_them(load_text):
    """As the original: a section is read when it names the constraint solver selected so
    far; the SQP settings inside it are read."""
    text = ("section SQP QP\ntime 9 0.5\nsection end\n"  # before: interiorPoint
            "constraintSolver SQP\n"
            "section SQP QP\nwarmStart 1\nconstraintType graphics\nconstraintOffset 1e-3\n"
            "useActiveSetConvergence\nsection end\n"
            "section interiorPoint\ndensity 5\nsection end\n" + CUBE)
    s = load_text(text)
    assert (s.duration, s.dt, s.density) == (5.0, 0.025, 1000.0)
    assert (s.constraint_solver, s.warm_start, s.constraint_type) == ("SQP", 1, "graphics")
    assert s.constraint_offset == 1e-3 and s.active_set_convergence


def test_section_without_end_skips_to_end_of_file(load_text):
    s = load_text(CUBE + "section QP\ntime 9 0.5\nsection\n")
    assert s.duration == 5.0
    assert any(":3: warning: `section QP` has no `section end`" in w for w in s.warnings)


def test_shape_line_continuation_and_comments(load_text):
    text = ("shapes input 2\n"
            "# a comment line inside the block is not a shape\n\n"
            "meshes/cube.msh 0 1 0  0 0 0  1 1 1 \\\n"
            "   # a comment line whose \\ still continues\n"
            "   DBC 0 0 0  1 0.1 1  0 -1 0  0 0 0  0.5 \\\n"
            "   NBC 0 0.9 0  1 1 1  0 5 0 # comment after the NBC\n"
            "meshes/cube.msh 0 3 0  0 0 0  1 1 1  material 2000 1e6 0.3  initVel 1 0 0  0 0 90\n")
    s = load_text(text)
    a, b = s.shapes
    assert a.line == 4 and a.dbc[0].line == 6 and a.nbc[0].line == 7
    assert a.dbc[0].time_range == (0.5, math.inf)
    assert a.dbc[0].linear_velocity == (0.0, -1.0, 0.0)
    assert a.nbc[0].acceleration == (0.0, 5.0, 0.0) and a.nbc[0].time_range == (0, math.inf)
    assert b.line == 8 and b.material.density == 2000 and b.init_velocity.angular_deg == (0, 0, 90)


def test_shape_extras(load_text):
    s = load_text("shapes input 2\n"
                  "meshes/cube.msh 0 0 0  0 0 0  1 1 1\n"
                  "meshes/tri.obj 0 2 0  10 20 30  1 2 3  linearVelocity 1 2 3 "
                  "angularVelocity 0 90 0 meshSeq meshes\n")
    t = s.shapes[1]
    assert t.kind == "surface" and t.rotation_deg == (10, 20, 30) and t.scale == (1, 2, 3)
    assert t.linear_velocity == (1, 2, 3) and t.angular_velocity_deg == (0, 90, 0)
    assert t.mesh_sequence.is_dir() and t.mesh_sequence.name == "meshes"


def test_shape_matrix_expands_x_outer_z_inner(load_text):
    s = load_text(CUBE + "shapeMatrix input 2 1 3\n\n"
                  "meshes/tri.obj 1 5 2  0 0 90  1 1 1\n")
    copies = s.shapes[1:]
    assert [c.translation for c in copies] == [
        (0, 0, 0), (0, 0, 2), (0, 0, 4), (1, 0, 0), (1, 0, 2), (1, 0, 4)]
    assert all(c.rotation_deg == (0, 0, 90) and c.dbc == () and c.linear_velocity is None
               and c.line == 5 for c in copies)
    s = load_text(CUBE + "shapeMatrix input 1 2 1  10 20 30\n"
                  "meshes/cube.msh 1 5 2  0 0 0  1 1 1 material 900 1e5 0.3\n")
    assert [c.translation for c in s.shapes[1:]] == [(10, 20, 30), (10, 25, 30)]
    assert s.shapes[2].material.density == 900


def test_half_space_normal_is_normalised(load_text):
    s = load_text("halfSpace 0 1 0  3 4 0  50 0.2\n" + CUBE)
    p = s.planes[0]
    assert p.kind == "halfSpace" and p.normal == pytest.approx((0.6, 0.8, 0.0))
    assert p.stiffness == 50 and p.friction == 0.2


def test_mesh_obstacle_with_and_without_rotation(load_text, scene_dir):
    s = load_text("meshCO meshes/plane.obj 0 -1 0  10  50 0.2 rotate 0 0 5\n"
                  "meshCO meshes/plane.obj 1 2 3  4  0 0\n" + CUBE)
    a, b = s.mesh_obstacles
    assert a.mesh_path == scene_dir / "meshes/plane.obj" and a.rotation_deg == (0, 0, 5)
    assert (a.size, a.stiffness, a.friction) == (10, 50, 0.2)
    assert b.position == (1, 2, 3) and b.rotation_deg == (0, 0, 0)


def test_clamped_values_warn(load_text):
    s = load_text("dampingStiff -1\ndampingRatio 2\nplayBackSpeed 0\n" + CUBE)
    assert (s.damping_stiff, s.damping_ratio, s.playback_speed) == (0.0, 1.0, 1.0)
    assert [w.split(": warning: ")[0][-2:] for w in s.warnings] == [":1", ":2", ":3"]


def test_solver_names_and_integrator(load_text):
    s = load_text("constraintSolver IP\nlinSysSolver EIGEN\ntimeIntegration NM 0.3 0.55\n"
                  "minBarrierStiffnessScale 1e9\nuseAbsParameters\nturnOffGravity\n" + CUBE)
    assert s.constraint_solver == "interiorPoint" and s.linear_solver == "eigen"
    assert (s.integrator, s.newmark_beta, s.newmark_gamma) == ("NM", 0.3, 0.55)
    assert s.kappa_min_multiplier == 1e9 and s.use_abs_parameters and not s.gravity
    assert load_text("linearSolver auto\n" + CUBE).linear_solver is None


def test_legacy_keywords(load_text, scene_dir):
    s = load_text("script twist\nhandleRatio 0.05\nsize 1\nrotateModel 0 1 0 45\n"
                  "restart status42\nDBCTimeRange 1 2\nNBCTimeRange 0.5\nappendStr tag\n"
                  "warmStart 3\nfricIterAmt -1\n" + CUBE)
    assert (s.script, s.handle_ratio, s.size) == ("twist", 0.05, 1.0)
    assert s.rotate_model == (0, 1, 0, 45) and s.restart == scene_dir / "status42"
    assert s.dbc_time_range == (1, 2) and s.nbc_time_range == (0.5, math.inf)
    assert (s.append_str, s.warm_start, s.friction_iterations) == ("tag", 3, -1)
    s = load_text("script fall 2 1.5 -3\n" + CUBE)
    assert s.script_params == (1.5, -3.0)


def test_ignored_and_no_op_keywords(load_text, scene_dir):
    s = load_text("view orthographic\nzoom 0.3\ncameraTracking\nCCDMethod TightInclusion\n"
                  "QPSolver Gurobi\ntimeStepper NM\ninexactSolve\nresolution 3\n" + CUBE)
    assert s.ignored == ("view orthographic", "zoom 0.3", "cameraTracking",
                         "CCDMethod TightInclusion", "QPSolver Gurobi")
    path = scene_dir / "scene.txt"
    assert s.warnings == tuple(
        f"{path}:{n}: warning: `{kw}` has no effect and is ignored (the original program "
        "does not know it either)" for n, kw in ((6, "timeStepper"), (7, "inexactSolve"),
                                                 (8, "resolution")))


def test_extra_numbers_are_ignored_with_a_warning(load_text):
    s = load_text("ground 0 0.5 50.0\n" + CUBE)
    assert s.planes[0].origin == (0, 0.5, 0) and s.planes[0].friction == 0
    (w,) = s.warnings
    assert ":1: warning: `ground` ignores the extra number 50.0" in w


def test_seg_and_pt_fall_back_to_obj(load_text, scene_dir):
    s = load_text(CUBE + "shapes input 3\n"
                  "meshes/fallback.seg 0 0 0 0 0 0 1 1 1\n"
                  "meshes/fallback.pt 0 0 0 0 0 0 1 1 1\n"
                  "meshes/edge.seg 0 0 0 0 0 0 1 1 1\n")
    seg, pt, real = s.shapes[1:]
    assert seg.mesh_path == scene_dir / "meshes/fallback.obj" and seg.kind == "segments"
    assert pt.mesh_path == scene_dir / "meshes/fallback.obj" and pt.kind == "points"
    assert real.mesh_path.suffix == ".seg" and real.kind == "segments" and real.mesh_kind is None
    assert [w.split(": warning: ")[0].rsplit(":", 1)[1] for w in s.warnings] == ["4", "5"]


def test_tetgen_mesh_without_extension(load_text, scene_dir):
    s = load_text("shapes input 2\nmeshes/tg 0 0 0 0 0 0 1 1 1\n"
                  "meshes/tg.ele 0 0 0 0 0 0 1 1 1\n")
    assert [sh.kind for sh in s.shapes] == ["tet", "tet"]
    assert s.shapes[0].mesh_path == scene_dir / "meshes/tg"


def test_initial_velocity_on_a_kinematic_shape_warns(load_text):
    s = load_text(CUBE + "shapes input 1\nmeshes/tri.obj 0 0 0 0 0 0 1 1 1 initVel 1 0 0 0 0 0\n")
    assert any(":4: warning: an initial velocity is ignored" in w for w in s.warnings)


# ----------------------------------------------------------------------------- paths


def test_paths_try_scene_folder_then_ancestors_then_cwd(tmp_path, monkeypatch):
    scene_dir = tmp_path / "a" / "b"
    scene_dir.mkdir(parents=True)
    for p in ("a/b/m/near.msh", "a/m/near.msh", "a/m/up.msh", "cwd/m/cwd.msh", "cwd/m/up.msh"):
        (tmp_path / p).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / p).write_text("")
    monkeypatch.chdir(tmp_path / "cwd")
    scene = scene_dir / "s.txt"
    text = ("shapes input 4\nm/near.msh 0 0 0 0 0 0 1 1 1\nm/up.msh 0 0 0 0 0 0 1 1 1\n"
            f"m/cwd.msh 0 0 0 0 0 0 1 1 1\n{tmp_path / 'a/m/near.msh'} 0 0 0 0 0 0 1 1 1\n")
    scene.write_text(text)
    near, up, cwd, absolute = (s.mesh_path for s in load_scene(scene).shapes)
    assert near == tmp_path / "a/b/m/near.msh"  # the scene's folder wins over an ancestor
    assert up == tmp_path / "a/m/up.msh"  # an ancestor wins over the current directory
    assert cwd == tmp_path / "cwd/m/cwd.msh"
    assert absolute == tmp_path / "a/m/near.msh"


def test_parse_txt_without_a_file_uses_the_current_directory(scene_dir, monkeypatch):
    monkeypatch.chdir(scene_dir)
    s = parse_txt(CUBE)
    assert s.source is None and s.shapes[0].mesh_path == Path(scene_dir / "meshes/cube.msh")
