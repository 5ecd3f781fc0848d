"""2D scenes at the command line: `convert` writes them back as TOML and refuses the text
form; `check` and `run` refuse them with one line naming the scene's dimension (exit 2,
nothing written) while the time step is 3D."""

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


def test_check_and_run_refuse_a_2d_scene_naming_its_dimension(tmp_path, capsys):
    src = tmp_path / "s.toml"
    src.write_text(SCENE)
    for argv in (["check", str(src)], ["run", str(src), "-o", str(tmp_path / "out"), "-q"]):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert err == f"{src}:2: 2D scenes cannot be simulated yet ([scene] dimension = 2)"
    assert not (tmp_path / "out").exists()
