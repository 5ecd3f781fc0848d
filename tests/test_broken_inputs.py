"""Every subcommand on broken inputs: exit status 2 (3 where the simulation itself fails),
one line on stderr that names the file to blame, no traceback, and not one byte of what
was on disk before changed (a pre-existing run folder above all).

Each case gets a fresh copy of one workspace: good meshes, a good scene and the complete
output folder of a short run of it (``prev/``); the case breaks something in its copy and
names the command. Commands run in-process through ``ipcsim.cli.main``.
"""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass
from pathlib import Path

import meshio
import numpy as np
import pytest
from generated import write_box_msh

from ipcsim.cli import main
from ipcsim.model.generate import box_tet_mesh

GOOD = ("shapes input 1\ncube.msh 0 0.01 0  0 0 0  1 1 1\nselfCollisionOff\nground 0 0\n"
        "time 0.04 0.01\n")
SHAPE = "cube.msh 0 0.01 0  0 0 0  1 1 1"


class Workspace:
    """A copy of the template: ``cube.msh``, ``good.txt``, ``prev/`` (a run of good.txt
    with 5 frames, its checkpoint at step 4)."""

    def __init__(self, root: Path):
        self.root = root
        self.prev = root / "prev"

    def p(self, name: str) -> str:
        return str(self.root / name)

    def text(self, name: str, content: str) -> str:
        path = self.root / name
        path.write_text(content)
        return str(path)

    def scene(self, body: str, name: str = "bad.txt") -> str:
        return self.text(name, body)

    def mesh_scene(self, mesh: str, name: str = "bad.txt", extra: str = "") -> str:
        return self.scene(f"shapes input 1\n{mesh} 0 0.01 0  0 0 0  1 1 1\nselfCollisionOff\n"
                          f"ground 0 0\ntime 0.04 0.01\n{extra}", name)

    def vtu(self, name: str, points, cells) -> str:
        meshio.write(self.p(name), meshio.Mesh(points, cells))
        return name

    def msh_lines(self) -> list[str]:
        return (self.root / "cube.msh").read_text().split("\n")

    def frame(self, k: int) -> Path:
        return self.prev / "frames" / f"frame_{k:06d}.vtu"

    def checkpoint(self, **changes) -> None:
        path = self.prev / "checkpoint.npz"
        with np.load(path) as data:
            ck = {key: data[key] for key in data.files}
        for key, value in changes.items():
            if value is None:
                del ck[key]
            else:
                ck[key] = value
        with open(path, "wb") as f:
            np.savez(f, **ck)

    def resume(self, *extra) -> list[str]:
        return ["run", self.p("good.txt"), "-o", str(self.prev), "-q", "--resume", *extra]


@dataclass
class Case:
    id: str
    build: object  # Workspace -> argv
    names: str  # fragment of the one stderr line (the file to blame)
    status: int = 2
    new: str | None = None  # a folder the command may create (a run that fails at step 1)
    started: str | None = None  # a study folder the command may create (and mark) before
    # it finds that its cluster cannot be reached


def _cut(path: Path, keep: float = 0.5) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * keep)])


def _msh_with_first_element_node(ws: Workspace, name: str, tag: str) -> str:
    lines = ws.msh_lines()
    first = lines.index("$Elements") + 3
    row = lines[first].split()
    row[1] = tag
    lines[first] = " ".join(row)
    return ws.text(name, "\n".join(lines))


POINTS, TETS = box_tet_mesh(1, 1, 1, size=(0.2, 0.2, 0.2), origin=(-0.1, 0.0, -0.1))
# a 1 m cube (cube.msh scaled 5x) with cube.msh wholly inside it, and one mesh of two
# nested parts: a solid inside a solid, though no surface crosses another
CUBE_IN_CUBE = ("shapes input 2\ncube.msh 0 0.01 0  0 0 0  5 5 5\n"
                "cube.msh 0 0.4 0  0 0 0  1 1 1\nground 0 0\ntime 0.04 0.01\n")
INNER_POINTS, INNER_TETS = box_tet_mesh(1, 1, 1, size=(0.05, 0.05, 0.05),
                                        origin=(-0.025, 0.075, -0.025))
NESTED = (np.concatenate([POINTS, INNER_POINTS]),
          [("tetra", np.concatenate([TETS, INNER_TETS + len(POINTS)]))])


# ----------------------------------------------------------------------------- run


def _run(ws, scene, *extra):
    return ["run", scene, "-o", str(ws.prev), "-q", "--overwrite", *extra]


def _run_new(ws, scene, *extra):
    return ["run", scene, "-o", ws.p("new"), "-q", *extra]


RUN = [
    Case("run unknown keyword", lambda ws: _run(ws, ws.scene("tiem 5\n" + GOOD)), "bad.txt:1"),
    Case("run non-numeric", lambda ws: _run(ws, ws.scene("density heavy\n" + GOOD)),
         "bad.txt:1"),
    Case("run unicode digit", lambda ws: _run(ws, ws.scene(GOOD + "time \u0661 0.01\n")),
         "bad.txt:6"),
    Case("run step count overflows", lambda ws: _run(ws, ws.scene(GOOD + "time 1e300 1e-10\n")),
         "bad.txt:6"),
    Case("run density 1e300", lambda ws: _run(ws, ws.scene(GOOD + "density 1e300\n")),
         "bad.txt:6"),
    Case("run fricIterAmt 1e20", lambda ws: _run(ws, ws.scene(
        GOOD + "fricIterAmt 100000000000000000000\n")), "bad.txt:6"),
    Case("run translation 1e200", lambda ws: _run(ws, ws.scene(
        "shapes input 1\ncube.msh 0 1e200 0  0 0 0  1 1 1\n")), "bad.txt:2"),
    Case("run mesh is a folder", lambda ws: (os.mkdir(ws.p("dir.msh")),
                                             _run(ws, ws.mesh_scene("dir.msh")))[1], "bad.txt:2"),
    Case("run mesh missing", lambda ws: _run(ws, ws.mesh_scene("gone.msh")), "bad.txt:2"),
    Case("run every tet twice", lambda ws: _run(ws, ws.mesh_scene(ws.vtu(
        "twice.vtu", POINTS, [("tetra", np.concatenate([TETS, TETS]))]))), "twice.vtu"),
    Case("run gmsh tag 0", lambda ws: (_msh_with_first_element_node(ws, "tag0.msh", "0"),
                                       _run(ws, ws.mesh_scene("tag0.msh")))[1], "tag0.msh"),
    Case("run gmsh negative tag", lambda ws: (_msh_with_first_element_node(ws, "neg.msh", "-5"),
                                              _run(ws, ws.mesh_scene("neg.msh")))[1],
         "neg.msh"),
    Case("run huge coordinates", lambda ws: _run(ws, ws.mesh_scene(ws.vtu(
        "huge.vtu", POINTS * 1e200, [("tetra", TETS)]))), "huge.vtu"),
    Case("run nan coordinates", lambda ws: _run(ws, ws.mesh_scene(ws.vtu(
        "nan.vtu", np.where(np.arange(24).reshape(8, 3) == 4, np.nan, POINTS),
        [("tetra", TETS)]))), "nan.vtu"),
    Case("run truncated msh", lambda ws: (ws.text("cut.msh", (ws.root / "cube.msh")
                                                  .read_text()[:700]),
                                          _run(ws, ws.mesh_scene("cut.msh")))[1], "cut.msh"),
    Case("run truncated vtu mesh", lambda ws: (ws.vtu("cut.vtu", POINTS, [("tetra", TETS)]),
                                               _cut(ws.root / "cut.vtu"),
                                               _run(ws, ws.mesh_scene("cut.vtu")))[2],
         "cut.vtu"),
    Case("run obj with a quad", lambda ws: (ws.text("quad.obj", "v 0 0 0\nv 1 0 0\nv 1 0 1\n"
                                                                "v 0 0 1\nf 1 2 3 4\n"),
                                            _run(ws, ws.scene(f"shapes input 2\n{SHAPE}\n"
                                                              "quad.obj 0 1 0 0 0 0 1 1 1\n")))[1],
         "quad.obj"),
    Case("run obj index out of range", lambda ws: (
        ws.text("far.obj", "v 0 0 0\nv 1 0 0\nv 0 0 1\nf 1 2 9\n"),
        _run(ws, ws.scene(f"shapes input 2\n{SHAPE}\nfar.obj 0 1 0 0 0 0 1 1 1\n")))[1],
        "far.obj"),
    Case("run restart timestep inf", lambda ws: (
        ws.text("status1", "timestep inf\nposition 8 3\n" + "0 0 0\n" * 8 + "velocity 24\n"
                + "0\n" * 24),
        _run(ws, ws.scene(GOOD + "restart status1\n")))[1], "status1"),
    Case("run scene is /dev/zero", lambda ws: (os.symlink("/dev/zero", ws.p("zero.txt")),
                                               _run(ws, ws.p("zero.txt")))[1], "zero.txt"),
    Case("run scene is a folder", lambda ws: (os.mkdir(ws.p("dir.txt")),
                                              _run(ws, ws.p("dir.txt")))[1], "dir.txt"),
    Case("run scene over 1 MiB", lambda ws: _run(ws, ws.scene(GOOD + "\n" * (1 << 20))),
         "bad.txt"),
    Case("run scene with NUL", lambda ws: _run(ws, ws.scene(GOOD + "\0" * 1000)), "bad.txt:6"),
    Case("run scene not UTF-8", lambda ws: (
        (ws.root / "latin.txt").write_bytes(GOOD.encode() + b"# caf\xe9\n"),
        _run(ws, ws.p("latin.txt")))[1], "latin.txt:6"),
    Case("run toml syntax", lambda ws: _run(ws, ws.scene("[time\ndt = 1\n", "bad.toml")),
         "bad.toml:1"),
    Case("run toml wrong type", lambda ws: _run(ws, ws.scene(
        '[[shapes]]\npath = "cube.msh"\n[time]\ndt = "fast"\n', "bad.toml")), "bad.toml:4"),
    Case("run toml huge integer", lambda ws: _run(ws, ws.scene(
        '[[shapes]]\npath = "cube.msh"\n[integrator]\nwarm_start = ' + "9" * 5000 + "\n",
        "bad.toml")), "bad.toml"),
    Case("run intersecting start", lambda ws: _run(ws, ws.scene(
        f"shapes input 2\n{SHAPE}\ncube.msh 0.05 0.05 0  0 0 0  1 1 1\nground 0 0\n")),
        "intersect"),
    Case("run a cube inside a cube", lambda ws: _run(ws, ws.scene(CUBE_IN_CUBE)),
         "shape 2 (cube) lies inside shape 1 (cube)"),
    Case("run nested parts of one mesh", lambda ws: _run(ws, ws.mesh_scene(ws.vtu(
        "nested.vtu", *NESTED))), "shape 1 (nested) has a part inside another"),
    Case("run below the ground", lambda ws: _run(ws, ws.scene(
        "shapes input 1\ncube.msh 0 -0.05 0  0 0 0  1 1 1\nground 0 0\n")), "below a plane"),
    Case("run appendStr with a slash", lambda ws: _run(ws, ws.scene(GOOD + "appendStr a/b\n")),
         "bad.txt:6"),
    Case("run scene stem '..'", lambda ws: ["run", ws.scene(GOOD, "...txt"), "-q"], "...txt"),
    Case("run -o missing/../prev", lambda ws: ["run", ws.p("good.txt"), "-o",
                                               ws.p("missing/../prev"), "-q"], "prev exists"),
    Case("run -o the current directory", lambda ws: ["run", ws.p("good.txt"), "-o", ".", "-q"],
         "current directory"),
    Case("run -o a file", lambda ws: ["run", ws.p("good.txt"), "-o", ws.p("good.txt"), "-q"],
         "not a folder"),
    Case("run initVel 1e200 (energy not finite)", lambda ws: _run_new(ws, ws.scene(
        "shapes input 1\ncube.msh 0 0.01 0  0 0 0  1 1 1 initVel 0 -1e200 0 0 0 0\n"
        "ground 0 0\ntime 0.04 0.01\n")), "energy is not finite", status=3, new="new"),
    Case("run E 1e308 (Hessian not finite)", lambda ws: _run_new(ws, ws.scene(
        "shapes input 1\ncube.msh 0 0.01 0  0 0 0  1 1 1 material 1000 1e308 0.4\n"
        "selfCollisionOff\nground 0 0\ntime 0.04 0.01\n")), "elasticity term", status=3,
        new="new"),
]


def _pardiso_installed() -> bool:
    from ipcsim.solver.linear import make_solver

    try:
        make_solver("pardiso")
    except ImportError:
        return False
    return True


PARDISO = [
    Case("run PARDISO without MKL", lambda ws: _run(ws, ws.scene(GOOD + "linearSolver PARDISO\n")),
         "bad.txt:6"),
    Case("check PARDISO without MKL", lambda ws: ["check", ws.scene(GOOD + "linearSolver PARDISO\n")],
         "bad.txt:6"),
]

# ----------------------------------------------------------------------------- check

CHECK = [
    Case("check intersecting start", lambda ws: ["check", ws.scene(
        f"shapes input 2\n{SHAPE}\ncube.msh 0.05 0.05 0  0 0 0  1 1 1\n")], "intersect"),
    Case("check a cube inside a cube", lambda ws: ["check", ws.scene(CUBE_IN_CUBE)],
         "lies inside"),
    Case("check nested parts of one mesh (self collision off)", lambda ws: [
        "check", ws.mesh_scene(ws.vtu("nested.vtu", *NESTED))], "has a part inside"),
    Case("check below the ground", lambda ws: ["check", ws.scene(
        "shapes input 1\ncube.msh 0 0 0  0 0 0  1 1 1\nground 0 0.05\n")], "below a plane"),
    Case("check every tet twice", lambda ws: ["check", ws.mesh_scene(ws.vtu(
        "twice.vtu", POINTS, [("tetra", np.concatenate([TETS, TETS]))]))], "twice.vtu"),
    Case("check unknown keyword", lambda ws: ["check", ws.scene(GOOD + "selfFrc 0.1\n")],
         "bad.txt:6"),
    Case("check missing scene", lambda ws: ["check", ws.p("none.txt")], "none.txt"),
    Case("check unknown extension", lambda ws: ["check", ws.scene(GOOD, "scene.yaml")],
         "scene.yaml"),
    Case("check a scene named with an escape sequence", lambda ws: [
        "check", ws.scene("tiem 1\n", "red\x1b[31m.txt")], "red\\x1b[31m.txt:1"),
]

# ----------------------------------------------------------------------------- check --frames


def _frames(ws):
    return ["check", "--frames", str(ws.prev)]


def _fewer_vertices(ws, k: int) -> None:
    mesh = meshio.read(ws.frame(k))
    meshio.write(ws.frame(k), meshio.Mesh(mesh.points[:4], [("tetra", np.array([[0, 1, 2, 3]]))]))


FRAMES = [
    Case("frames truncated vtu", lambda ws: (_cut(ws.frame(2)), _frames(ws))[1],
         "frame_000002.vtu"),
    Case("frames empty vtu", lambda ws: (ws.frame(3).write_bytes(b""), _frames(ws))[1],
         "frame_000003.vtu"),
    Case("frames garbage series", lambda ws: ((ws.prev / "frames" / "series.pvd")
                                              .write_text("<VTKFile <<"), _frames(ws))[1],
         "series.pvd"),
    Case("frames series is a folder", lambda ws: (
        (ws.prev / "frames" / "series.pvd").unlink(),
        (ws.prev / "frames" / "series.pvd").mkdir(), _frames(ws))[2], "series.pvd"),
    Case("frames different vertex count", lambda ws: (_fewer_vertices(ws, 2), _frames(ws))[1],
         "frame_000002.vtu"),
    Case("frames listed frame missing", lambda ws: (ws.frame(4).unlink(), _frames(ws))[1],
         "frame_000004.vtu"),
    Case("frames no frames folder", lambda ws: (shutil.rmtree(ws.prev / "frames"),
                                                _frames(ws))[1], "series.pvd"),
    Case("frames damaged scene.toml", lambda ws: ((ws.prev / "scene.toml").write_text(
        "[time\n"), _frames(ws))[1], "scene.toml:1"),
    Case("frames empty series", lambda ws: ((ws.prev / "frames" / "series.pvd").write_text(
        '<VTKFile type="Collection"><Collection></Collection></VTKFile>'), _frames(ws))[1],
        "lists no frames"),
    Case("frames cells out of range", lambda ws: (meshio.write(ws.frame(1), meshio.Mesh(
        meshio.read(ws.frame(1)).points, [("tetra", np.array([[0, 1, 2, 99]]))])),
        _frames(ws))[1], "frame_000001.vtu"),
]

# ----------------------------------------------------------------------------- convert

CONVERT = [
    Case("convert onto itself", lambda ws: ["convert", ws.p("good.txt"), ws.p("good.txt")],
         "good.txt"),
    Case("convert onto itself through ..", lambda ws: [
        "convert", ws.p("good.txt"), ws.p("prev/../good.txt")], "good.txt"),
    Case("convert existing target", lambda ws: ["convert", ws.p("good.txt"),
                                                ws.text("old.toml", "# mine\n")], "old.toml"),
    Case("convert broken source", lambda ws: ["convert", ws.scene("tiem 1\n"), ws.p("o.toml")],
         "bad.txt:1"),
    Case("convert unknown target extension", lambda ws: ["convert", ws.p("good.txt"),
                                                         ws.p("o.yaml")], "o.yaml"),
    Case("convert into a missing folder", lambda ws: ["convert", ws.p("good.txt"),
                                                      ws.p("nowhere/o.toml")], "o.toml"),
    Case("convert target is a folder", lambda ws: (os.mkdir(ws.p("d.toml")), [
        "convert", ws.p("good.txt"), ws.p("d.toml")])[1], "d.toml"),
]

# ----------------------------------------------------------------------------- compare


def _twin(ws) -> Path:
    twin = ws.root / "twin"
    shutil.copytree(ws.prev, twin)
    return twin


COMPARE = [
    Case("compare truncated frame", lambda ws: (_cut(_twin(ws) / "frames" / "frame_000002.vtu"),
                                                ["compare", str(ws.prev), ws.p("twin")])[1],
         "frame_000002.vtu"),
    Case("compare plot unwritable", lambda ws: ["compare", str(ws.prev), str(ws.prev),
                                                "--plot", ws.p("nowhere/plot.png")],
         "plot.png"),
    Case("compare missing B", lambda ws: ["compare", str(ws.prev), ws.p("none")], "none"),
    Case("compare steps.csv is a folder", lambda ws: (
        (_twin(ws) / "steps.csv").unlink(), (ws.root / "twin" / "steps.csv").mkdir(),
        ["compare", str(ws.prev), ws.p("twin")])[2], "steps.csv"),
    Case("compare damaged golden", lambda ws: ["compare", str(ws.prev),
                                               ws.text("g.json", '{"format": "ipcsim-golden-1"')],
         "g.json"),
    Case("compare different vertex counts", lambda ws: _compare_fewer_vertices(ws),
         "vertex counts"),
]


def _compare_fewer_vertices(ws) -> list[str]:
    """B: a copy of prev/ whose every frame has fewer vertices."""
    twin = Workspace(ws.root)
    twin.prev = _twin(ws)
    for k in range(5):
        _fewer_vertices(twin, k)
    return ["compare", str(ws.prev), str(twin.prev)]


# ----------------------------------------------------------------------------- render

RENDER = [
    Case("render azimuth inf", lambda ws: ["render", str(ws.prev), "--azimuth", "inf"],
         "--azimuth"),
    Case("render truncated frame", lambda ws: (_cut(ws.frame(1)), ["render", str(ws.prev),
                                                                   "-q"])[1], "frame_000001.vtu"),
    Case("render different vertex count", lambda ws: (_fewer_vertices(ws, 3),
                                                      ["render", str(ws.prev), "-q"])[1],
         "frame_000003.vtu"),
    Case("render no frames", lambda ws: (shutil.rmtree(ws.prev / "frames"),
                                         ["render", str(ws.prev), "-q"])[1], "no frames"),
    Case("render empty range", lambda ws: ["render", str(ws.prev), "--frames", "5:2"],
         "--frames"),
    Case("render damaged scene.toml", lambda ws: ((ws.prev / "scene.toml").write_text(
        "[[planes]]\nkind = 'wall'\n"), ["render", str(ws.prev), "-q"])[1], "scene.toml:2"),
    Case("render missing folder", lambda ws: ["render", ws.p("none"), "-q"], "none"),
]

# ----------------------------------------------------------------------------- --resume

RESUME = [
    Case("resume negative step", lambda ws: (ws.checkpoint(step=np.int64(-1)),
                                             ws.resume())[1], "checkpoint.npz"),
    Case("resume step beyond the run", lambda ws: (ws.checkpoint(step=np.int64(40)),
                                                   ws.resume())[1], "step 40"),
    Case("resume empty checkpoint", lambda ws: ((ws.prev / "checkpoint.npz").write_bytes(b""),
                                                ws.resume())[1], "checkpoint.npz"),
    Case("resume checkpoint missing key", lambda ws: (ws.checkpoint(v=None), ws.resume())[1],
         "checkpoint.npz"),
    Case("resume checkpoint wrong types", lambda ws: (ws.checkpoint(x=np.full((8, 3), "a")),
                                                      ws.resume())[1], "checkpoint.npz"),
    Case("resume checkpoint scalar arrays", lambda ws: (ws.checkpoint(x=np.float64(1.0)),
                                                        ws.resume())[1], "checkpoint.npz"),
    Case("resume checkpoint of another state", lambda ws: (
        ws.checkpoint(x=np.load(ws.prev / "checkpoint.npz")["x"] + 1e-3), ws.resume())[1],
        "frame_000004.vtu"),
    Case("resume checkpoint format 1", lambda ws: (ws.checkpoint(format_version=np.int64(1)),
                                                   ws.resume())[1], "format 1"),
    Case("resume checkpoint not a zip", lambda ws: (
        (ws.prev / "checkpoint.npz").write_text("hello"), ws.resume())[1], "checkpoint.npz"),
    Case("resume steps.csv is a folder", lambda ws: (
        (ws.prev / "steps.csv").unlink(), (ws.prev / "steps.csv").mkdir(), ws.resume())[2],
        "steps.csv"),
    Case("resume steps.csv short", lambda ws: ((ws.prev / "steps.csv").write_text(
        "\n".join((ws.prev / "steps.csv").read_text().split("\n")[:3]) + "\n"),
        ws.resume())[1], "steps.csv"),
    Case("resume steps.csv damaged row", lambda ws: ((ws.prev / "steps.csv").write_text(
        (ws.prev / "steps.csv").read_text().replace("\n2,", "\nx,", 1)), ws.resume())[1],
        "steps.csv:3"),
    Case("resume newton.csv other columns", lambda ws: ((ws.prev / "newton.csv").write_text(
        "a,b\n1,2\n"), ws.resume())[1], "newton.csv"),
    Case("resume frame missing", lambda ws: (ws.frame(2).unlink(), ws.resume())[1],
         "frame_000002.vtu"),
    Case("resume mesh content changed", lambda ws: (write_box_msh(
        ws.root / "cube.msh", cells=(1, 1, 1), size=(0.21, 0.2, 0.2)), ws.resume())[1],
        "not the scene"),
    Case("resume scene setting changed", lambda ws: ((ws.root / "good.txt").write_text(
        GOOD + "density 900\n"), ws.resume())[1], "not the scene"),
    Case("resume series is a folder", lambda ws: (
        (ws.prev / "frames" / "series.pvd").unlink(),
        (ws.prev / "frames" / "series.pvd").mkdir(), ws.resume())[2], "series.pvd"),
    Case("resume --steps before the checkpoint", lambda ws: ws.resume("--steps", "2"),
         "--steps 2"),
    Case("resume missing folder", lambda ws: ["run", ws.p("good.txt"), "-o", ws.p("none"),
                                              "-q", "--resume"], "none"),
    Case("resume without checkpoint", lambda ws: ((ws.prev / "checkpoint.npz").unlink(),
                                                  ws.resume())[1], "nothing to resume"),
    Case("resume a folder of the user's", lambda ws: (ws.text("mine/notes.txt", "mine")
                                                      if os.mkdir(ws.p("mine")) is None else 0,
                                                      ["run", ws.p("good.txt"), "-o",
                                                       ws.p("mine"), "-q", "--resume"])[1],
         "nothing to resume"),
]

# ----------------------------------------------------------------------------- sweep

STUDY = '[study]\nscene = "good.txt"\n\n[[vary]]\n"time.dt" = [0.01, 0.02]\n'


def _study(ws, text: str = STUDY) -> str:
    return ws.text("study.toml", text)


def _sweep(ws, *extra, study: str | None = None):
    return ["sweep", study or _study(ws), "-o", ws.p("study_out"), "--serial", "-q", *extra]


def _users_study_files(ws, folder: str = ".") -> None:
    (ws.root / folder).mkdir(exist_ok=True)
    (ws.root / folder / "study.csv").write_text("trial,result\n1,good\n")
    (ws.root / folder / "study.png").write_bytes(b"\x89PNG mine")


SWEEP = [
    Case("sweep -o . holding the user's study.csv", lambda ws: (
        _users_study_files(ws), ["sweep", _study(ws), "-o", ".", "--serial", "-q"])[1],
        "current directory"),
    Case("sweep -o a folder holding the user's study.csv", lambda ws: (
        _users_study_files(ws, "mine"), ["sweep", _study(ws), "-o", ws.p("mine"),
                                         "--serial", "-q"])[1], "--overwrite"),
    Case("sweep -o a run's folder", lambda ws: ["sweep", _study(ws), "-o", str(ws.prev),
                                                "--serial", "-q"], "holds an ipcsim run"),
    Case("sweep --overwrite onto a run's folder", lambda ws: [
        "sweep", _study(ws), "-o", str(ws.prev), "--serial", "-q", "--overwrite"],
        "holds an ipcsim run"),
    Case("sweep range of infinitely many values", lambda ws: _sweep(ws, study=_study(
        ws, STUDY.replace("[0.01, 0.02]", "{ start = 0.01, stop = 0.02, step = 5e-324 }"))),
        "study.toml:5"),
    Case("sweep range spanning 2e308", lambda ws: _sweep(ws, study=_study(
        ws, STUDY.replace("[0.01, 0.02]", "{ start = -1e308, stop = 1e308, step = 1e307 }"))),
        "study.toml:5"),
    Case("sweep linear range spanning 2e308", lambda ws: _sweep(ws, study=_study(
        ws, STUDY.replace("[0.01, 0.02]", "{ start = -1e308, stop = 1e308, num = 3 }"))),
        "run 0 (time.dt = -1e+308)"),
    Case("sweep --scheduler unknown scheme", lambda ws: [
        "sweep", _study(ws), "-o", ws.p("study_out"), "--scheduler", "foo://host:8786"],
        "foo://host:8786"),
    Case("sweep --scheduler port not a number", lambda ws: [
        "sweep", _study(ws), "-o", ws.p("study_out"), "--scheduler", "tcp://host:abc"],
        "tcp://host:abc"),
    Case("sweep --scheduler bad IPv6 address", lambda ws: [
        "sweep", _study(ws), "-o", ws.p("study_out"), "--scheduler", "tcp://[::1:8786"],
        "tcp://[::1:8786"),
    Case("sweep --scheduler tls:// without a TLS context", lambda ws: [
        "sweep", _study(ws), "-o", ws.p("study_out"), "--scheduler", "tls://127.0.0.1:1"],
        "tls://127.0.0.1:1", started="study_out"),
    Case("sweep study.scene is a FIFO", lambda ws: (os.mkfifo(ws.p("fifo.txt")), _sweep(
        ws, study=_study(ws, STUDY.replace("good.txt", "fifo.txt"))))[1], "not a regular file"),
    Case("sweep study file over 1 MiB", lambda ws: _sweep(ws, study=_study(
        ws, STUDY + "#" * (1 << 20))), "a study file is a few KB"),
    Case("sweep a scene whose mesh is a FIFO", lambda ws: (
        os.mkfifo(ws.p("fifo.msh")), ws.mesh_scene("fifo.msh", "fifo.txt"),
        _sweep(ws, study=_study(ws, STUDY.replace("good.txt", "fifo.txt"))))[2],
        "'fifo.msh' is not a regular file (a device, a pipe or a socket)"),
    Case("sweep chart.y names no column", lambda ws: _sweep(ws, study=_study(
        ws, STUDY + '\n[chart]\ny = "newton_iters"\n')), "study.toml:8"),
]

CASES = RUN + CHECK + FRAMES + CONVERT + COMPARE + RENDER + RESUME + SWEEP
if not _pardiso_installed():
    CASES += PARDISO


def test_the_suite_is_broad():
    commands = {c.id.split()[0] for c in CASES}
    assert {"run", "check", "frames", "convert", "compare", "render", "resume",
            "sweep"} <= commands
    assert len({c.id for c in CASES}) == len(CASES) >= 60


@pytest.fixture(scope="module")
def template(tmp_path_factory):
    root = tmp_path_factory.mktemp("template")
    write_box_msh(root / "cube.msh", cells=(1, 1, 1))
    (root / "good.txt").write_text(GOOD)
    cwd = os.getcwd()
    os.chdir(root)
    try:
        assert main(["run", "good.txt", "-o", "prev", "-q"]) == 0
    finally:
        os.chdir(cwd)
    return root


def snapshot(root: Path) -> dict[str, bytes | None]:
    """Every file's bytes and every folder (None), by path relative to ``root``."""
    out: dict[str, bytes | None] = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for d in dirnames:
            out[os.path.relpath(os.path.join(dirpath, d), root)] = None
        for f in filenames:
            path = os.path.join(dirpath, f)
            rel = os.path.relpath(path, root)
            if os.path.islink(path):
                out[rel] = os.readlink(path).encode()
            else:  # a FIFO a case made is no file to read (it would block)
                out[rel] = Path(path).read_bytes() if os.path.isfile(path) else b"special"
    return out


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_broken_input_is_one_clear_line(case, template, tmp_path, monkeypatch, capsys):
    root = tmp_path / "ws"
    shutil.copytree(template, root, symlinks=True)
    monkeypatch.chdir(root)
    ws = Workspace(root)
    argv = case.build(ws)
    before = snapshot(root)
    capsys.readouterr()

    status = main(argv)

    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert status == case.status, captured.err
    assert "Traceback" not in captured.err + captured.out
    assert "\x1b" not in captured.err  # a name's escape sequence is shown escaped
    assert len(lines) == 1, captured.err
    assert case.names in lines[0], lines[0]
    after = snapshot(root)
    changed = [p for p, content in before.items() if after.get(p, b"gone") != content]
    assert changed == [], f"changed or removed: {changed}"
    created = [p for p in after if p not in before
               and Path(p).parts[0] not in (case.new, case.started)]
    assert created == [], f"created: {created}"
    if case.new:  # a run that failed in the simulation keeps what it wrote before
        assert (root / case.new / "frames" / "frame_000000.vtu").is_file()
