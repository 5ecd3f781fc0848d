"""`ipcsim compare`: identical, perturbed and mismatched runs, and original OBJ output."""

from __future__ import annotations

import shutil
from pathlib import Path

import meshio
import pytest
from generated import write_box_msh

from ipcsim.cli import main
from ipcsim.io.compare import surface_vertices


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("compare")
    write_box_msh(tmp / "cube.msh")
    two = tmp / "two.txt"
    two.write_text("shapes input 2\ncube.msh -0.3 0.05 0  0 0 0  1 1 1\n"
                   "cube.msh 0.3 0.05 0  0 0 0  1 1 1\nselfCollisionOff\nground 0 0\n"
                   "time 0.05 0.01\n")
    one = tmp / "one.txt"
    one.write_text("shapes input 1\ncube.msh 0 0.05 0  0 0 0  1 1 1\nselfCollisionOff\n"
                   "ground 0 0\ntime 0.05 0.01\n")
    a, b, c = tmp / "a", tmp / "b", tmp / "c"
    for scene, out in ((two, a), (two, b), (one, c)):
        assert main(["run", str(scene), "-o", str(out), "--steps", "3", "-q"]) == 0
    return a, b, c


def test_identical_runs_are_the_same(runs, tmp_path, capsys):
    a, b, _ = runs
    plot = tmp_path / "diff.png"
    assert main(["compare", str(a), str(b), "--plot", str(plot)]) == 0
    assert "same within tolerance" in capsys.readouterr().out
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_perturbed_frame_is_named(runs, tmp_path, capsys):
    a, b, _ = runs
    p = tmp_path / "p"
    shutil.copytree(b, p)
    f = p / "frames" / "frame_000002.vtu"
    mesh = meshio.read(f)
    mesh.points[5, 0] += 1e-3
    meshio.write(f, mesh)
    assert main(["compare", str(a), str(p)]) == 1
    out = capsys.readouterr().out
    assert "frame_000002.vtu" in out and "position" in out
    # within a loose tolerance it is the same again
    assert main(["compare", str(a), str(p), "--atol", "2e-3"]) == 0


def test_different_log_counts_are_named(runs, tmp_path, capsys):
    a, b, _ = runs
    p = tmp_path / "p"
    shutil.copytree(b, p)
    lines = (p / "steps.csv").read_text().splitlines()
    cols = lines[0].split(",")
    k = cols.index("newton_iterations")
    row = lines[2].split(",")
    row[k] = str(int(row[k]) + 1)
    lines[2] = ",".join(row)
    (p / "steps.csv").write_text("\n".join(lines) + "\n")
    assert main(["compare", str(a), str(p)]) == 1
    assert "step 2: newton_iterations" in capsys.readouterr().out


def test_adaptive_runs_with_different_steps_compare_by_their_frames(tmp_path, capsys):
    """Adaptive runs at two tolerances land on the same frames by different steps: their
    frames are compared, their logs (a row per attempted step) are not, and the summary
    says so; fixed-step logs of different steps still cannot be compared."""
    bar = Path(__file__).parents[2] / "input" / "spinning_bar.txt"
    folders = []
    for tau in ("1e-2", "1e-3"):
        folders.append(tmp_path / tau)
        assert main(["run", str(bar), "-o", str(folders[-1]), "-q", "--set",
                     "integrator.type='BDF2'", "--set", "time.duration=0.1", "--set",
                     f"time.tolerance={tau}"]) == 0
    assert main(["compare", *map(str, folders), "--atol", "1e-2"]) == 0
    out = capsys.readouterr().out
    assert "compared 5 frames" in out and "same within tolerance" in out
    assert "steps.csv not compared: A logs" in out and "(adaptive time steps)" in out
    assert main(["compare", *map(str, folders)]) == 1  # apart by more than 1e-6 of l
    assert "DIFFERENT: first at frame" in capsys.readouterr().out


def test_mismatched_folders_cannot_be_compared(runs, tmp_path, capsys):
    a, b, c = runs
    assert main(["compare", str(a), str(c)]) == 2
    assert "different vertex counts" in capsys.readouterr().err
    p = tmp_path / "p"
    shutil.copytree(b, p)
    (p / "frames" / "frame_000003.vtu").unlink()
    assert main(["compare", str(a), str(p)]) == 2
    assert "frame_000003 in A but not in B" in capsys.readouterr().err
    (p / "frames" / "frame_000003.vtu").write_bytes((b / "frames" / "frame_000003.vtu")
                                                    .read_bytes())
    (p / "steps.csv").unlink()
    assert main(["compare", str(a), str(p)]) == 2
    assert "missing file" in capsys.readouterr().err
    assert main(["compare", str(a), str(tmp_path / "absent")]) == 2


def _write_original(a, folder, perturb_step=None):
    """The original program's <n>.obj: surface vertices in global order, faces shuffled."""
    folder.mkdir()
    for f in sorted((a / "frames").glob("frame_*.vtu")):
        step = int(f.stem.split("_")[1])
        mesh = meshio.read(f)
        index = surface_vertices(mesh)
        x = mesh.points[index].copy()
        if step == perturb_step:
            x[3] += 0.01
        lines = [f"v {p[0]:.17g} {p[1]:.17g} {p[2]:.17g}" for p in x]
        lines += ["f 1 2 3", "f 3 2 4"]  # faces are not compared
        (folder / f"{step}.obj").write_text("\n".join(lines) + "\n")


def test_original_obj_output(runs, tmp_path, capsys):
    a, _, _ = runs
    same, moved = tmp_path / "orig", tmp_path / "moved"
    _write_original(a, same)
    _write_original(a, moved, perturb_step=1)
    assert main(["compare", str(a), str(same)]) == 0
    assert "surface vertices" in capsys.readouterr().out
    assert main(["compare", str(a), str(moved)]) == 1
    assert "frame_000001.vtu vs 1.obj" in capsys.readouterr().out
    # a missing <n>.obj cannot be compared
    (same / "2.obj").unlink()
    assert main(["compare", str(a), str(same)]) == 2
    assert "no <n>.obj for steps 2" in capsys.readouterr().err


def _moved(src, dst, shift=(0.0, 0.0, 0.0), frame0_vertex=None):
    """A copy of run ``src`` with every frame moved by ``shift`` and, where given, a
    vertex of frame 0 set to ``frame0_vertex``."""
    shutil.copytree(src, dst)
    for f in sorted((dst / "frames").glob("frame_*.vtu")):
        mesh = meshio.read(f)
        mesh.points = mesh.points + shift
        if frame0_vertex is not None and f.name == "frame_000000.vtu":
            mesh.points[0] = frame0_vertex
        meshio.write(f, mesh)
    return dst


@pytest.mark.parametrize("bad", [float("nan"), float("inf")])
def test_a_non_finite_first_frame_never_makes_runs_the_same(runs, tmp_path, capsys, bad):
    """The tolerance's scale comes from A's first frame: a NaN or infinite coordinate
    there must not make it NaN or infinite (and every difference pass)."""
    a, _, _ = runs
    broken = _moved(a, tmp_path / "broken", frame0_vertex=(bad, 0.0, 0.0))
    far = _moved(a, tmp_path / "far", shift=(0.5, 0.0, 0.0))
    assert main(["compare", str(broken), str(far)]) == 1
    out = capsys.readouterr().out
    assert "DIFFERENT" in out and "frame_000000.vtu" in out, out


def test_a_golden_reference_that_samples_no_vertex_cannot_compare(runs, tmp_path, capsys):
    import json

    from ipcsim.io.compare import golden_from_run, write_golden

    a, _, _ = runs
    with pytest.raises(ValueError, match="at least one vertex"):
        golden_from_run(a, vertices=0)
    golden = golden_from_run(a)
    golden["vertices"] = []
    golden["frames"] = [{**f, "positions": []} for f in golden["frames"]]
    path = write_golden(tmp_path / "empty.json", golden)
    assert main(["compare", str(a), str(path)]) == 2
    err = capsys.readouterr().err
    assert "empty.json" in err and "no vertex" in err, err
    assert json.loads(path.read_text())["vertices"] == []


def test_a_golden_reference_sampling_a_vertex_the_mesh_lacks_cannot_compare(runs, tmp_path,
                                                                            capsys):
    from ipcsim.io.compare import golden_from_run, write_golden

    a, _, _ = runs
    golden = golden_from_run(a)
    golden["vertices"][-1] = golden["mesh"]["vertices"] + 5
    path = write_golden(tmp_path / "far.json", golden)
    assert main(["compare", str(a), str(path)]) == 2
    err = capsys.readouterr().err
    assert "far.json" in err and "not among the mesh's" in err and len(err.splitlines()) == 1


def test_a_golden_reference_whose_vertices_are_not_whole_numbers_cannot_compare(runs, tmp_path,
                                                                                 capsys):
    """[0.5, ...] was read as vertex 0 and compared (exit 1): a damaged reference."""
    from ipcsim.io.compare import golden_from_run, write_golden

    a, _, _ = runs
    golden = golden_from_run(a)
    golden["vertices"] = [v + 0.5 for v in golden["vertices"]]
    path = write_golden(tmp_path / "halves.json", golden)
    assert main(["compare", str(a), str(path)]) == 2
    err = capsys.readouterr().err
    assert "halves.json" in err and "whole numbers" in err
