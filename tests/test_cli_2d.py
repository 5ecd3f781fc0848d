"""2D scenes at the command line: `convert` writes them back as TOML and refuses the text
form; `check`, `run`, `check --frames` and `--resume` take them, and an intersecting
start is refused with one line (exit 2)."""

from __future__ import annotations

from ipcsim.cli import main
from ipcsim.scene import load_scene

SCENE = """[scene]
dimension = 2
[[shapes]]
kind = "rectangle"
size = [1.0, 1.0]
resolution = [2, 2]
[[planes]]
kind = "ground"
height = -1.0
"""


def test_convert_keeps_a_2d_scene_in_toml_and_refuses_the_text_form(tmp_path, capsys):
    src = tmp_path / "s.toml"
    src.write_text(SCENE)
    assert main(["convert", str(src), str(tmp_path / "back.toml")]) == 0
    assert load_scene(tmp_path / "back.toml") == load_scene(src)
    assert main(["convert", str(src), str(tmp_path / "s.txt")]) == 2
    err = capsys.readouterr().err.strip()
    assert "a 2D scene has no text form" in err and "\n" not in err
    assert not (tmp_path / "s.txt").exists()


def test_check_and_run_take_a_2d_scene(tmp_path, capsys):
    src = tmp_path / "s.toml"
    src.write_text(SCENE + "[time]\nduration = 0.05\ndt = 0.01\n")
    assert main(["check", str(src)]) == 0
    out = tmp_path / "out"
    assert main(["run", str(src), "-o", str(out), "-q", "--steps", "3"]) == 0
    assert (out / "steps.csv").read_text().count("\n") == 4  # the header and 3 steps
    # --resume from the checkpoint: the run completes its 5 steps
    assert main(["run", str(src), "-o", str(out), "-q", "--resume"]) == 0
    assert (out / "steps.csv").read_text().count("\n") == 6
    assert len(list((out / "frames").glob("frame_*.vtu"))) == 6
    assert main(["check", "--frames", str(out)]) == 0
    # --set: a scene value overridden from the command line
    assert main(["run", str(src), "-o", str(tmp_path / "set"), "-q",
                 "--set", "time.duration=0.02"]) == 0
    assert (tmp_path / "set" / "steps.csv").read_text().count("\n") == 3


def test_check_refuses_an_intersecting_2d_start(tmp_path, capsys):
    src = tmp_path / "s.toml"
    src.write_text(SCENE.replace("height = -1.0", "height = 0.0"))
    assert main(["check", str(src)]) == 2
    err = capsys.readouterr().err.strip()
    assert "on or below a plane" in err and "\n" not in err


def test_render_draws_a_2d_run_seen_from_z(tmp_path):
    from ipcsim.io.render import _read_frame, is_planar, load_run_frames

    src = tmp_path / "s.toml"
    src.write_text(SCENE + "[time]\nduration = 0.02\ndt = 0.01\n")
    out = tmp_path / "out"
    assert main(["run", str(src), "-o", str(out), "-q"]) == 0
    assert is_planar(_read_frame(load_run_frames(out).paths[0]))
    assert main(["render", str(out), "--gif"]) == 0
    assert len(list((out / "render").glob("frame_*.png"))) == 3
    assert (out / "render" / "animation.gif").stat().st_size > 0


def test_damping_is_refused_in_a_2d_scene_naming_the_key(tmp_path, capsys):
    src = tmp_path / "s.toml"
    src.write_text(SCENE + "[integrator]\ndamping_ratio = 0.1\n")
    assert main(["check", str(src)]) == 2
    err = capsys.readouterr().err.strip()
    assert "damping_ratio" in err and "2D" in err and "\n" not in err
