"""Bad scenes: every mistake is `path:line: message`, exit status 2, no traceback."""

from __future__ import annotations

import pytest

from ipcsim import cli
from ipcsim.errors import SceneError
from ipcsim.scene import load_scene

CUBE = "shapes input 1\nmeshes/cube.msh 0 0 0  0 0 0  1 1 1\n"
OBJ = "shapes input 1\nmeshes/tri.obj 0 0 0  0 0 0  1 1 1\n"


def shape(extra: str) -> str:
    return f"shapes input 1\nmeshes/cube.msh 0 0 0  0 0 0  1 1 1 {extra}\n"


# (id, scene text, expected line or None, fragments the message must contain)
TXT_CASES = [
    ("unknown keyword", "tiem 5 0.01\n" + CUBE, 1,
     ["unknown keyword 'tiem'", "did you mean 'time'"]),
    ("shape extra typo", shape("materal 1000 1e5 0.3"), 2,
     ["unknown shape extra 'materal'", "did you mean 'material'"]),
    ("missing argument", "time\n" + CUBE, 1, ["`time` is missing duration"]),
    ("missing second argument", "stiffness 1e5\n" + CUBE, 1, ["missing Poisson ratio"]),
    ("non-numeric argument", "density heavy\n" + CUBE, 1, ["must be a number, got 'heavy'"]),
    ("non-numeric optional argument", "time 5 abc\n" + CUBE, 1,
     ["time step dt must be a number, got 'abc'"]),
    ("non-numeric on shape line", "shapes input 1\nmeshes/cube.msh 0 x 0 0 0 0 1 1 1\n", 2,
     ["translation y must be a number, got 'x'"]),
    ("too few numbers after tol", "tol 3\n1e-2\n1e-3\n", 1,
     ["`tol 3` expects 3 numbers", "ends after 2"]),
    ("word among tol values", "tol 2\n1e-2\nselfFric 0.1\n" + CUBE, 3,
     ["expects 2 numbers", "got 'selfFric'"]),
    ("values on the tol line", "tol 2 1e-2 1e-3\n1 2\n" + CUBE, 1,
     ["from the following lines", "'1e-2'"]),
    ("values on the tuning line", "tuning 1 0\n0\n" + CUBE, 1, ["from the following lines"]),
    ("keyword on the last tol value line", "tol 1\n1e-2 selfCollisionOff\n" + CUBE, 2,
     ["unexpected 'selfCollisionOff' after the 1 value(s) of `tol`"]),
    ("missing mesh", "shapes input 1\nmeshes/nope.msh 0 0 0 0 0 0 1 1 1\n", 2,
     ["mesh file 'meshes/nope.msh' not found"]),
    ("missing seg and obj", "shapes input 1\nmeshes/nope.seg 0 0 0 0 0 0 1 1 1\n", 2,
     ["'meshes/nope.seg' not found"]),
    ("unknown mesh extension", "shapes input 1\nmeshes/cube.stl 0 0 0 0 0 0 1 1 1\n", 2,
     ["unknown mesh file extension '.stl'"]),
    ("missing mesh sequence", shape("meshSeq nowhere"), 2,
     ["mesh sequence folder 'nowhere' not found"]),
    ("missing restart", "restart status7\n" + CUBE, 1, ["restart file 'status7' not found"]),
    ("shapes count too high", "shapes input 2\nmeshes/cube.msh 0 0 0 0 0 0 1 1 1\nselfFric 0\n",
     3, ["found the keyword `selfFric`", "declares 2 shapes but has only 1 shape line"]),
    ("shapes block ends early", "shapes input 2\nmeshes/cube.msh 0 0 0 0 0 0 1 1 1\n", 1,
     ["declares 2 shape lines but the file ends after 1"]),
    ("too few shape numbers", "shapes input 1\nmeshes/cube.msh 0 0 0 0 0 0 1 1\n", 2,
     ["shape line is missing scale z"]),
    ("tenth number on shape line", shape("7"), 2, ["unexpected number '7'"]),
    ("short DBC", shape("DBC 0 0 0 1 1 1 0 0 0 0 0"), 2, ["`DBC` is missing angular velocity z"]),
    ("DBC box inverted", shape("DBC 1 0 0 0 1 1 0 0 0 0 0 0"), 2,
     ["`DBC` box min corner is above the max corner on the x axis"]),
    ("DBC window reversed", shape("DBC 0 0 0 1 1 1 0 0 0 0 0 0 3 2"), 2,
     ["`DBC` time range starts after it ends"]),
    ("tokens after continuation", shape("\\ DBC"), 2, ["after the line continuation"]),
    ("dt zero", "time 5 0\n" + CUBE, 1, ["`time` step dt must be > 0"]),
    ("dt negative", "time 5 -0.1\n" + CUBE, 1, ["`time` step dt must be > 0"]),
    ("duration shorter than dt", "time 0.01 0.025\n" + CUBE, 1,
     ["is shorter than one time step"]),
    ("E zero", "stiffness 0 0.4\n" + CUBE, 1, ["Young's modulus must be > 0"]),
    ("nu one half", "stiffness 1e5 0.5\n" + CUBE, 1, ["Poisson ratio must lie in [0.0, 0.5)"]),
    ("nu negative", "stiffness 1e5 -0.1\n" + CUBE, 1, ["Poisson ratio must lie in"]),
    ("shape nu", shape("material 1000 1e5 0.7"), 2, ["`material` Poisson ratio must lie in"]),
    ("negative density", "density -1\n" + CUBE, 1, ["`density` must be > 0"]),
    ("negative shape density", shape("material -5 1e5 0.3"), 2, ["`material` density must be > 0"]),
    ("negative selfFric", "selfFric -0.1\n" + CUBE, 1, ["`selfFric` must be >= 0"]),
    ("negative ground friction", "ground -0.1 0\n" + CUBE, 1, ["`ground` friction must be >= 0"]),
    ("negative halfSpace friction", "halfSpace 0 0 0 0 1 0 50 -1\n" + CUBE, 1,
     ["`halfSpace` friction must be >= 0"]),
    ("negative meshCO friction", "meshCO meshes/plane.obj 0 0 0 1 0 -1\n" + CUBE, 1,
     ["`meshCO` friction must be >= 0"]),
    ("zero halfSpace normal", "halfSpace 0 0 0 0 0 0 50 0\n" + CUBE, 1, ["is the zero vector"]),
    ("meshCO not obj", "meshCO meshes/cube.msh 0 0 0 1 0 0\n" + CUBE, 1,
     ["`meshCO` needs an .obj"]),
    ("empty scene", "selfFric 0.1\n", None, ["the scene has no shapes"]),
    ("comment-only scene", "# nothing here\n\n", None, ["the scene has no shapes"]),
    ("no tet shape", OBJ, 2, ["no tetrahedral shape", "at least one simulated body"]),
    ("nan", "dHat nan\n" + CUBE, 1, ["must be a finite number, got 'nan'"]),
    ("inf where finite", "time inf\n" + CUBE, 1, ["must be a finite number, got 'inf'"]),
    ("overflow", "selfFric 1e999\n" + CUBE, 1, ["must be a finite number"]),
    ("integer expected", "warmStart 1.5\n" + CUBE, 1, ["must be a whole number, got '1.5'"]),
    ("warmStart range", "warmStart 6\n" + CUBE, 1, ["`warmStart` must be an integer 0..5"]),
    ("STIV constraints", "constraintSolver SQP\nconstraintType STIV\n" + CUBE, 2,
     ["constraint type 'STIV' is not implemented by ipcsim", "volume, graphics"]),
    ("unknown constraint type", "constraintType volum\n" + CUBE, 1,
     ["unknown constraint type 'volum'", "did you mean 'volume'"]),
    ("negative offset", "constraintOffset -1e-3\n" + CUBE, 1, ["must be >= 0"]),
    ("unknown solver", "constraintSolver interiorPt\n" + CUBE, 1,
     ["unknown constraint solver", "did you mean 'interiorPoint'"]),
    ("unsupported script", "script hang\n" + CUBE, 1,
     ["script 'hang' is not supported", "null, fall, fallNoShift"]),
    ("unknown energy", "energy StVK\n" + CUBE, 1, ["unknown energy 'StVK'"]),
    ("unknown integrator", "timeIntegration RK4\n" + CUBE, 1, ["unknown time integrator"]),
    ("newmark beta zero", "timeIntegration NM 0 0.5\n" + CUBE, 1, ["beta must be > 0"]),
    ("kappa zero", "kappa 0\n" + CUBE, 1, ["`kappa` must be > 0"]),
    ("negative tuning kappa", "tuning 1\n-5\n" + CUBE, 2, ["kappa must be > 0, or 0"]),
    ("dhat zero", "dHat 0\n" + CUBE, 1, ["`dHat` (or `tuning` entry 3) must be > 0"]),
    ("dhat homotopy upward", "tuning 3\n0\n1e-4\n1e-3\n" + CUBE, 3,
     ["initial dHat", "must not be smaller than the target"]),
    ("negative dHatAbs", "dHatAbs -1\n" + CUBE, 1, ["`dHatAbs` must be > 0"]),
    ("tol zero", "tol 1\n0\n" + CUBE, 1, ["`tol` must be > 0"]),
    ("tol count zero", "tol 0\n" + CUBE, 1, ["`tol` count must be >= 1"]),
    ("mirrored tet shape", "shapes input 1\nmeshes/cube.msh 0 0 0 0 0 0 -1 1 1\n", 2,
     ["mirrors the mesh"]),
    ("flat shape", "shapes input 1\nmeshes/cube.msh 0 0 0 0 0 0 1 0 1\n", 2,
     ["has a zero component"]),
    ("word after arguments", "time 5 0.025 selfCollisionOff\n" + CUBE, 1,
     ["unexpected 'selfCollisionOff' after its arguments"]),
    ("unknown section name", "section QPP\n" + CUBE, 1, ["`section` names solvers"]),
    ("rotateModel zero axis", "rotateModel 0 0 0 30\n" + CUBE, 1, ["axis is the zero vector"]),
    ("shapeMatrix extra", CUBE + "shapeMatrix input 1 1 1\nmeshes/cube.msh 0 0 0 0 0 0 1 1 1 "
     "linearVelocity 1 0 0\n", 4, ["takes only the `material` extra"]),
    ("shapeMatrix too big", "shapeMatrix input 1000 1000 1000\nmeshes/cube.msh 0 0 0 0 0 0 1 1 1\n",
     1, ["1000000000 copies"]),
    ("unknown linear solver", "linearSolver MUMPS\n" + CUBE, 1, ["unknown linear solver"]),
    ("appendStr with two words", "appendStr a b\n" + CUBE, 1, ["unexpected 'b'"]),
]


def check_bad_scene(path, line, fragments, capsys):
    """The library raises SceneError(path, line, ...); the CLI prints it and returns 2."""
    with pytest.raises(SceneError) as info:
        load_scene(path)
    err = info.value
    assert err.line == line
    where = f"{path}:{line}: " if line else f"{path}: "
    assert str(err).startswith(where)
    for fragment in fragments:
        assert fragment in err.message
    target = path.with_name("converted.toml")
    assert cli.main(["convert", str(path), str(target)]) == 2
    stderr = capsys.readouterr().err
    assert stderr.startswith(where) and fragments[0] in stderr
    assert "Traceback" not in stderr
    assert not target.exists()


@pytest.mark.parametrize("text,line,fragments", [c[1:] for c in TXT_CASES],
                         ids=[c[0] for c in TXT_CASES])
def test_bad_text_scene(write_scene, capsys, text, line, fragments):
    check_bad_scene(write_scene(text), line, fragments, capsys)


BASE_TOML = '[[shapes]]\npath = "meshes/cube.msh"\n'
TOML_CASES = [
    ("unknown table", "[tiem]\ndt = 1\n" + BASE_TOML, 1, ["unknown key tiem", "'time'"]),
    ("unknown key", "[time]\ndt = 0.01\nduraton = 3\n" + BASE_TOML, 3,
     ["unknown key time.duraton", "did you mean 'duration'"]),
    ("unknown nested key", BASE_TOML + '[[shapes]]\npath = "meshes/cube.msh"\n[[shapes.dbc]]\n'
     "box_min = [0, 0, 0]\nbox_max = [1, 1, 1]\nvelocty = [1, 0, 0]\n", 8,
     ["unknown key shapes[1].dbc[0].velocty", "did you mean 'linear_velocity'"]),
    ("unknown inline key", BASE_TOML + "material = {density = 1, youngs_modulus = 1e5, "
     "poison_ratio = 0.3}\n", 3, ["shapes[0].material.poison_ratio", "'poisson_ratio'"]),
    ("wrong type", '[time]\ndt = "fast"\n' + BASE_TOML, 2,
     ["time.dt must be a number, got a string ('fast')"]),
    ("table expected", "time = 5\n" + BASE_TOML, 1, ["time must be a table"]),
    ("bool expected", "[contact]\nself_collision = 1\n" + BASE_TOML, 2,
     ["contact.self_collision must be true or false"]),
    ("integer expected", "[integrator]\nwarm_start = 1.5\n" + BASE_TOML, 2,
     ["integrator.warm_start must be an integer"]),
    ("vector length", BASE_TOML + "translation = [0, 1]\n", 3,
     ["shapes[0].translation must have 3 numbers, got 2"]),
    ("vector element", BASE_TOML + 'scale = [1, "x", 1]\n', 3,
     ["shapes[0].scale[1] must be a number"]),
    ("missing path", "[[shapes]]\ntranslation = [0, 0, 0]\n", 1,
     ["shapes[0] is missing the required key 'path'"]),
    ("missing mesh", '[[shapes]]\npath = "meshes/none.msh"\n', 2, ["'meshes/none.msh' not found"]),
    ("syntax error", "[time\n" + BASE_TOML, 1, ["invalid TOML"]),
    ("bad value", "[time]\ndt = \n" + BASE_TOML, 2, ["invalid TOML"]),
    ("empty", "", None, ["the scene has no shapes"]),
    ("dt zero", "[time]\ndt = 0.0\n" + BASE_TOML, 2, ["time.dt must be > 0"]),
    ("nan", "[contact]\ndhat = nan\n" + BASE_TOML, 2, ["contact.dhat must be a finite number"]),
    ("damping ratio above one", "[integrator]\ndamping_ratio = 2.0\n" + BASE_TOML, 2,
     ["integrator.damping_ratio must lie in [0, 1]"]),
    ("ground with normal", BASE_TOML + '[[planes]]\nkind = "ground"\nheight = 0\n'
     "normal = [0, 1, 0]\n", 6, ["takes only friction and height"]),
    ("zero normal", BASE_TOML + '[[planes]]\nkind = "halfSpace"\norigin = [0, 0, 0]\n'
     "normal = [0, 0, 0]\n", 6, ["planes[0].normal [0.0, 0.0, 0.0] is the zero vector"]),
    ("negative plane friction", BASE_TOML + '[[planes]]\nkind = "ground"\nheight = 0\n'
     "friction = -1\n", 6, ["planes[0].friction must be >= 0"]),
    ("kappa word", '[contact]\nkappa = "auto"\n' + BASE_TOML, 2, ['a number or "adaptive"']),
    ("CMR", '[solver]\nconstraint_solver = "QP"\nconstraint_type = "CMR"\n' + BASE_TOML, 3,
     ["'CMR' is not implemented by ipcsim"]),
    ("matrix with velocity", BASE_TOML + "matrix = {counts = [2, 1, 1], spacing = [1, 1, 1]}\n"
     "linear_velocity = [0, 1, 0]\n", 4, ["a shape with `matrix` takes only"]),
    ("kind mismatch", BASE_TOML + 'kind = "segments"\n', 3, ["does not fit the tet mesh"]),
    ("no tet shape", '[[shapes]]\npath = "meshes/tri.obj"\n', 1, ["no tetrahedral shape"]),
]


@pytest.mark.parametrize("text,line,fragments", [c[1:] for c in TOML_CASES],
                         ids=[c[0] for c in TOML_CASES])
def test_bad_toml_scene(write_scene, capsys, text, line, fragments):
    check_bad_scene(write_scene(text, "scene.toml"), line, fragments, capsys)


@pytest.mark.parametrize("args,fragment", [
    (["missing.txt", "out.toml"], "scene file not found"),
    (["scene.yaml", "out.toml"], "unknown scene file extension '.yaml'"),
    (["ok.txt", "out.json"], "unknown scene file extension '.json'"),
    (["ok.txt", "no/such/folder/out.toml"], "does not exist"),
    (["folder.txt", "out.toml"], "is a folder"),
    (["latin1.txt", "out.toml"], "not UTF-8"),
])
def test_cli_file_problems(scene_dir, capsys, monkeypatch, args, fragment):
    monkeypatch.chdir(scene_dir)
    (scene_dir / "ok.txt").write_text(CUBE)
    (scene_dir / "scene.yaml").write_text("")
    (scene_dir / "folder.txt").mkdir()
    (scene_dir / "latin1.txt").write_bytes(b"# caf\xe9\n" + CUBE.encode())
    assert cli.main(["convert", *args]) == 2
    err = capsys.readouterr().err
    assert fragment in err and "Traceback" not in err


def test_undecodable_byte_reports_its_line(write_scene):
    path = write_scene("")
    path.write_bytes(CUBE.encode() + b"time 5 \xff\n")
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert info.value.line == 3
